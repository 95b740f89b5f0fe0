"""The test that counts: install the built zip the way users do (Install from Disk)
into a temporary Blender user directory, enable it, and scan through its operator.

Runs in a subprocess so the installed copy (``bl_ext.user_default.rls_addon``) never
meets the source-tree copy the other Blender tests register.
"""

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import importlib.machinery, json, sys
class OnlyBundledEmbree:
    # A user's Blender has no embreex of its own: hide any copy outside the extensions'
    # site-packages (this venv has one for the tests), so the bundled wheel must serve.
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] != 'embreex':
            return None
        bundled = [p for p in sys.path if '/extensions/' in p]
        if path is not None:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, bundled)
        if spec is None:
            raise ImportError('embreex: not in the extension site-packages')
        return spec
sys.meta_path.insert(0, OnlyBundledEmbree())
import bpy
zip_path, out_dir = sys.argv[1], sys.argv[2]
res = bpy.ops.extensions.package_install_files(filepath=zip_path, repo='user_default',
                                               enable_on_install=True)
assert res == {'FINISHED'}, res
mods = [m for m in bpy.context.preferences.addons.keys() if m.endswith('rls_addon')]
scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob)
mesh = bpy.data.meshes.new('Ground')
mesh.from_pydata([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], [], [(0, 1, 2, 3)])
ground = bpy.data.objects.new('Ground', mesh)
scene.collection.objects.link(ground)
scene.cursor.location = (0.0, 0.0, 2.0)
assert bpy.ops.object.rls_add_lidar(preset='generic_uniform32') == {'FINISHED'}
lidar = bpy.context.active_object
lidar.rls_lidar.noise = False
lidar.rls_lidar.output_dir = out_dir
assert bpy.ops.rls.scan_frame() == {'FINISHED'}
preview = bpy.data.objects[lidar.name + ' points']
import rls_addon  # must NOT be importable: the installed copy lives under bl_ext
# The bundled Embree wheel: installed into the extensions' own site-packages and used
# from there (put first on sys.path so a copy elsewhere cannot stand in for it).
import importlib, os, numpy as np
site = [p for p in sys.path if 'extensions' in p and p.rstrip('/').endswith('site-packages')]
embree = {'site': site}
if site:
    sys.path.insert(0, site[0])
    import embreex
    embree['embreex_file'] = embreex.__file__
    backends = importlib.import_module(mods[0] + '.core.casting')
    factory, notice = backends.caster_factory('embree')
    c = factory(np.array([[-1.0, -1, 0], [3, -1, 0], [-1, 3, 0]]), np.array([[0, 1, 2]]))
    dist, tri = c.cast(np.array([[0.0, 0, 2]]), np.array([[0.0, 0, -1], [0, 0, 1]]), 10.0)
    embree.update(notice=notice, name=c.name, mode=getattr(c, 'mode', None), describe=c.describe(),
                  dist=[float(x) for x in dist], tri=[int(x) for x in tri],
                  status=list(backends.backend_status('auto')))
print(json.dumps({'modules': mods, 'preview_points': len(preview.data.vertices),
                  'package': type(lidar.rls_lidar).__module__, 'embree': embree}))
"""


def test_install_zip_and_scan_through_installed_operator(tmp_path):
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    # make build writes one zip per platform; this machine's is the Linux x64 one.
    zip_path = ROOT / "dist" / f"rls_addon-{manifest['version']}-linux_x64.zip"
    if not zip_path.exists():
        pytest.fail(f"{zip_path} is missing: run 'make build' (make test does)")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    out = tmp_path / "out"
    # Run from an empty directory so the source tree's rls_addon is not importable.
    script = SCRIPT.replace("import rls_addon  # must NOT be importable: the installed copy lives under bl_ext\n",
                            "assert 'rls_addon' not in sys.modules\n")
    proc = subprocess.run([sys.executable, "-c", script, str(zip_path), str(out)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert info["modules"] == ["bl_ext.user_default.rls_addon"]
    assert info["package"].startswith("bl_ext.user_default.rls_addon")
    files = sorted(p.name for p in out.iterdir())
    clouds = [f for f in files if f.endswith(".pcd")]
    assert len(clouds) == 1 and clouds[0].replace(".pcd", ".json") in files
    from rls_addon.core.output.io import read_cloud

    points = read_cloud(out / clouds[0])
    assert len(points) == info["preview_points"] > 1000
    assert (tmp_path / "user" / "extensions" / "user_default" / "rls_addon").is_dir()
    # The Embree wheel bundled for this platform is installed and usable.
    embree = info["embree"]
    assert embree["site"], "Blender put no extension site-packages on sys.path"
    assert embree["embreex_file"].startswith(str(tmp_path / "user")), embree
    assert embree["notice"] is None and embree["name"] == "embree", embree
    assert embree["mode"] == "packets", embree
    assert "C loop" in embree["describe"], embree  # the compiled loop shipped in the zip
    # What the LiDAR panel says under its backend choice (ui/lidar.py).
    assert embree["status"][0] == "embree", embree
    assert embree["status"][1].startswith("Embree with the compiled loop"), embree
    assert abs(embree["dist"][0] - 2.0) < 1e-5 and embree["tri"] == [0, -1], embree
