"""RLS's roadside detector judged by ``rls evaluate``, as a user runs the loop: the
sample intersection with its traffic, a Hesai Pandar64 on the traffic-light pole 'TL SW'
looking into the junction, ``rls dataset`` -> ``rls detect`` -> ``rls evaluate``. The
detector must find at least 85% of the vehicles that carry at least 50 points inside the
InfraLOB at BEV IoU 0.5, with at least 85% precision: poles, signs and buildings are
not vehicles."""

import json

import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

MOUNT = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes import build_scene
from rls_addon.blender.scenes.build import mount_position
scene = bpy.context.scene
build_scene("intersection", scene)
x, y, z = mount_position(bpy.data.objects["TL SW"])
lidar = bpy.data.objects.new("L TL SW", None)
lidar.location = (x, y, z)
lidar.rotation_euler = (0.0, math.radians(15.0), math.atan2(-y, -x))  # into the junction
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id = True, "hesai_pandar64"
s.use_sweep_start, s.sweep_start = True, 180.0  # the seam behind the pole
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    folder = tmp_path_factory.mktemp("detector")
    blend = build_blend(folder, "intersection.blend", MOUNT)
    proc = rls("dataset", blend, "--layout", "kitti", "--frames", "1-60", "--out", folder / "ds")
    assert proc.returncode == 0, proc.stderr
    root = folder / "ds" / "L_TL_SW"
    proc = rls("detect", root, "--out", folder / "det")
    assert proc.returncode == 0, proc.stderr
    return {"folder": folder, "blend": blend, "root": root, "det": folder / "det",
            "detect_stdout": proc.stdout}


def test_the_detector_finds_the_vehicles_in_the_region(loop):
    out = loop["folder"] / "result.json"
    proc = rls("evaluate", "--truth", loop["root"], "--detections", loop["det"],
               "--lob", f"{loop['blend']}:InfraLOB", "--min-points", "50", "--out", out)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(out.read_text())
    got = res["classes"]["vehicle"]["all"]["bev"]["0.5"]
    recall = got["tp"] / got["gt"]
    precision = got["tp"] / (got["tp"] + got["fp"])
    assert got["gt"] >= 40, got  # enough vehicles in view to mean something
    assert recall >= 0.85 and precision >= 0.85, (recall, precision, got)
    assert got["ap_r40"] >= 0.8 and got["ap_voc"] >= 0.8, got


def test_detections_are_files_of_the_dataset_and_name_the_detector(loop):
    files = sorted(p.name for p in loop["det"].glob("*.txt"))
    assert files[0] == "000001.txt" and files[-1] == "000060.txt" and len(files) == 60
    assert "60 frames of L_TL_SW" in loop["detect_stdout"]
    # the background it learned is said, on stdout and in detector.json beside the files
    assert "Background: empty scene: 5 sweep(s) per sensor" in loop["detect_stdout"]
    about = json.loads((loop["det"] / "detector.json").read_text())
    assert about["background"]["kind"] == "empty" and about["background"]["sweeps"] == {
        "L_TL_SW": 5}
    assert about["size_priors"].startswith("the scene's")
    lines = [ln.split() for p in loop["det"].glob("*.txt") for ln in p.read_text().splitlines()]
    assert lines and all(len(ln) == 9 and ln[7] in ("Vehicle", "Pedestrian", "Cyclist")
                         for ln in lines)
    assert all(0.0 < float(ln[8]) <= 1.0 for ln in lines)


def test_detect_refuses_to_overwrite_and_unknown_background_frames(loop, tmp_path):
    line = one_line_error(rls("detect", loop["root"], "--out", loop["det"]))
    assert "already holds detection files" in line and "--overwrite" in line
    line = one_line_error(rls("detect", loop["root"], "--out", tmp_path / "d",
                              "--background-frames", "70-80"))
    assert "background frames [70, 71, 72, 73, 74]" in line
    assert not (tmp_path / "d").exists()
