"""The UI operators of the installed extension (``bl_ext.user_default.rls_addon``): user
presets go to Blender's per-extension user folder; scan, range scan, metrics work.

Runs in a subprocess with a temporary Blender user directory (see
test_installed_extension.py); needs ``python tools/build_extension.py`` first."""

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import json, os, sys
import bpy
zip_path, out_dir = sys.argv[1], sys.argv[2]
assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo='user_default',
                                                enable_on_install=True) == {'FINISHED'}
assert 'rls_addon' not in sys.modules
scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob)
mesh = bpy.data.meshes.new('Ground')
mesh.from_pydata([(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)], [], [(0, 1, 2, 3)])
ground = bpy.data.objects.new('Ground', mesh)
ground['rls_label'] = 'road'
scene.collection.objects.link(ground)
scene.cursor.location = (0.0, 0.0, 2.0)
assert bpy.ops.object.rls_add_lidar(preset='velodyne_vlp16') == {'FINISHED'}
lidar = bpy.context.active_object
lidar.rls_lidar.output_dir = out_dir
fov = [c.name for c in lidar.children if c.get('rls_fov')]
assert bpy.ops.rls.preset_save(name='Installed Test') == {'FINISHED'}
scene.frame_start, scene.frame_end = 1, 2
assert bpy.ops.rls.scan_range() == {'FINISHED'}
scene.cursor.location = (0.0, 0.0, 0.0)
assert bpy.ops.object.rls_add_infralob(size_x=40, size_y=40) == {'FINISHED'}
scene.rls.metric_disks = 100
assert bpy.ops.rls.compute_metrics() == {'FINISHED'}
try:
    bpy.ops.rls.preset_delete(preset='velodyne_vlp16')
    refused = False
except RuntimeError as exc:
    refused = 'read-only' in str(exc)
print(json.dumps({'fov': fov, 'preset': lidar.rls_lidar.preset,
                  'infra_d': scene.rls.infra_d, 'refused': refused,
                  'menus': [hasattr(bpy.types, 'VIEW3D_MT_rls_add_' + f)
                            for f in ('spinning', 'mems', 'risley')]}))
"""


def test_installed_extension_ui_operators(tmp_path):
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    # make build writes one zip per platform; this machine's is the Linux x64 one.
    zip_path = ROOT / "dist" / f"rls_addon-{manifest['version']}-linux_x64.zip"
    if not zip_path.exists():
        pytest.fail(f"{zip_path} is missing: run 'make build' (make test does)")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    env.pop("RLS_USER_PRESET_DIR", None)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(zip_path), str(out)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert info["fov"] == ["LiDAR FOV"] and info["preset"] == "installed_test"
    assert info["refused"] and all(info["menus"]) and info["infra_d"] > 0
    saved = list((tmp_path / "user").rglob("installed_test.toml"))
    assert len(saved) == 1, saved
    assert saved[0].parent.parts[-4:] == (".user", "user_default", "rls_addon", "presets")
    assert len(list(out.glob("*.pcd"))) == 2
