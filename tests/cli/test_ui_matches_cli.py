"""What Blender's menus and panels write is what the command line writes: each operator
runs in a bpy-module subprocess (as a script or the UI calls it, without a window) and
the command in another, as a user runs it, and their files are compared byte for byte
(or, for a .blend, object by object)."""

import filecmp
import json
import subprocess
import sys

import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, build_blend, rls

# The sample intersection with its LiDAR (TL SW) and a second one on TL NE.
BUILD = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.lidars import add_lidar
from rls_addon.blender.scenes import add_sample_lidar, build_scene
from rls_addon.core.scene.mounting import LidarMounting
build_scene("intersection", bpy.context.scene)
add_sample_lidar("intersection", bpy.context.scene)
add_lidar(bpy.context.scene, LidarMounting(preset="hesai_pandar64", name="North",
                                           mount="TL NE", pitch_deg=10, face_region=True))
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""

# Opens argv[2] (when given, else an empty file), registers RLS and runs argv[3].
OPERATOR = r"""
import json, sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
if sys.argv[2]:
    bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
else:
    bpy.ops.wm.read_factory_settings(use_empty=True)
rls_addon.ensure_registered()
result = eval(sys.argv[3], {"bpy": bpy})
print(json.dumps(sorted(result)))
"""


def run_operator(blend, call, cwd=None):
    """Run ``call`` (e.g. ``bpy.ops.rls.export_dataset(...)``) on ``blend`` in a bpy
    subprocess; return its CompletedProcess (the operator's result on stdout's last line)."""
    proc = subprocess.run([sys.executable, "-c", OPERATOR, str(ROOT), str(blend or ""), call],
                          capture_output=True, text=True, timeout=900, cwd=cwd)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def same_tree(a, b):
    """Every file under ``a`` and ``b`` (relative paths) with the same bytes."""
    files = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    assert files == {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    assert files
    different = [str(f) for f in sorted(files) if not filecmp.cmp(a / f, b / f, shallow=False)]
    assert not different, different


@pytest.fixture(scope="module")
def junction(tmp_path_factory):
    return build_blend(tmp_path_factory.mktemp("junction"), "junction.blend", BUILD)


@pytest.mark.parametrize("layout", ["kitti", "opv2v"])
def test_export_dataset_writes_what_rls_dataset_writes(junction, tmp_path, layout):
    cli = tmp_path / "cli"
    proc = rls("dataset", junction, "--layout", layout, "--frames", "24-26", "--out", cli)
    assert proc.returncode == 0, proc.stderr
    ui = tmp_path / "ui"
    op = run_operator(junction, f"bpy.ops.rls.export_dataset(directory={str(ui)!r}, "
                                f"layout={layout!r}, use_scene_range=False, frame_start=24, "
                                "frame_end=26)")
    assert json.loads(op.stdout.splitlines()[-1]) == ["FINISHED"]
    same_tree(cli, ui)
