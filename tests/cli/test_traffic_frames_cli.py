"""Frames outside the traffic's keys (issue #37, #38): a scan, dataset or study asked for
frames after the traffic's last key or before its first is refused with one line and
nothing written, instead of scanning the road users frozen at their end poses."""

import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

SCENE = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes.build import (car, collection, infralob, mount_pole,
                                            standard_materials)
scene = bpy.context.scene
scene.render.fps = 10
scene.frame_start, scene.frame_end = 1, 60
box("Road", (-40, -20, -0.1), (40, 20, 0.0), label="road")
mats = standard_materials()
car(collection(scene, "Vehicles"), "Car", mats["paint"], [(-20.0, -2.0), (20.0, -2.0)],
    [3, 21])
infralob(scene, "InfraLOB", -15, 15, -10, 10)
mount_pole(collection(scene, "Poles"), "Pole", -12.0, 8.0, 6.0, mats["steel"], "pole",
           base_z=0.0)
lidar = bpy.data.objects.new("LiDAR", None)
lidar.location = (0.0, -8.0, 3.0)
scene.collection.objects.link(lidar)
lidar.rls_lidar.is_lidar = True
lidar.rls_lidar.preset = "generic_uniform32"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def keyed(tmp_path_factory):
    """A 60-frame scene whose only road user is keyed over frames 3-21."""
    return build_blend(tmp_path_factory.mktemp("keyed"), "keyed.blend", SCENE)


def test_frames_outside_the_traffic_are_refused(keyed, tmp_path):
    out = tmp_path / "data"
    line = one_line_error(rls("dataset", keyed, "--layout", "kitti", "--frames", "1-200", "--out", out))
    assert "1-2 before its first key (frame 3)" in line
    assert "22-200 after its last key (frame 21)" in line and "3-21" in line
    assert not out.exists() or not any(out.rglob("*"))
    line = one_line_error(rls("study", keyed, "--traffic", "500-510", "--out",
                              tmp_path / "s1"))
    assert "traffic frames 500-510 after its last key (frame 21)" in line
    line = one_line_error(rls("study", keyed, "--evaluate", "900-905", "--out",
                              tmp_path / "s2"))
    assert "frames 900-905 after its last key (frame 21)" in line  # --traffic defaults to them
    assert not (tmp_path / "s1").exists() and not (tmp_path / "s2").exists()
    line = one_line_error(rls("scan", keyed, "--frames", "30", "--out", tmp_path / "scan"))
    assert "frames 30 after its last key (frame 21)" in line
    proc = rls("scan", keyed, "--frames", "5-6", "--out", tmp_path / "scan")
    assert proc.returncode == 0, proc.stderr
