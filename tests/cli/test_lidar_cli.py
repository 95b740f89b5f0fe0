"""``rls lidar add|list|remove`` as a batch user runs them: a LiDAR added on a mount or
at a point is listed where it was put and scans; bad input ends with one error line and
writes nothing; the scene read is never changed without --overwrite."""

import hashlib
import json
import math

import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

# A ground, a 6 m pole marked as a mount at (10, 0) and a 20 x 10 m InfraLOB centred at
# (0, 5): from the pole the region's middle lies at yaw atan2(5, -10).
SCENE = SCENE_SCRIPT_HEAD + r"""
ground = box("Ground", (-30, -30, -0.1), (30, 30, 0.0), label="road")
pole = box("Pole", (9.9, -0.1, 0.0), (10.1, 0.1, 6.0))
pole["rls_mount"] = True
me = bpy.data.meshes.new("lob")
me.from_pydata([(-10, 0, 0), (10, 0, 0), (10, 10, 0), (-10, 10, 0)], [], [(0, 1, 2, 3)])
lob = bpy.data.objects.new("InfraLOB", me)
lob["rls_infralob"] = True
bpy.context.scene.collection.objects.link(lob)
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return build_blend(tmp_path_factory.mktemp("lidar"), "pole.blend", SCENE)


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def listed(path):
    proc = rls("lidar", "list", path, "--json")
    assert proc.returncode == 0, proc.stderr
    return {r["name"]: r for r in json.loads(proc.stdout)["lidars"]}


def test_add_on_a_mount_facing_the_region_list_scan_remove(scene, tmp_path):
    before = digest(scene)
    out = tmp_path / "one.blend"
    proc = rls("lidar", "add", scene, "--preset", "hesai_pandar64", "--mount", "Pole",
               "--pitch", 10, "--face-region", "--name", "Pole LiDAR", "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert digest(scene) == before  # the scene read is left as it was
    row = listed(out)["Pole LiDAR"]
    # on the pole's top plus the default mount offset of 0.25 m
    assert row["position_m"] == pytest.approx([10.0, 0.0, 6.25], abs=1e-4)
    assert row["yaw_deg"] == pytest.approx(math.degrees(math.atan2(5.0, -10.0)), abs=1e-3)
    assert row["pitch_deg"] == pytest.approx(10.0, abs=1e-3)
    assert row["device"] == "Hesai Pandar64"
    assert listed(scene) == {}
    # a second one at a point, the file changed in place
    proc = rls("lidar", "add", out, "--preset", "livox_avia", "--at", "0,-5,3", "--yaw",
               "-90", "--out", out, "--overwrite")
    assert proc.returncode == 0, proc.stderr
    rows = listed(out)
    assert sorted(rows) == ["LiDAR", "Pole LiDAR"]
    assert rows["LiDAR"]["position_m"] == pytest.approx([0, -5, 3])
    assert rows["LiDAR"]["yaw_deg"] == pytest.approx(-90)
    scan = rls("scan", out, "--sensor", "Pole LiDAR", "--frames", "1", "--out", tmp_path / "scan")
    assert scan.returncode == 0, scan.stderr
    assert json.loads(scan.stdout)["points"] > 1000
    # the progress line gives the frame's wall time and what it went on
    assert "s wall (frame " in scan.stderr and ", scan " in scan.stderr, scan.stderr
    # without --out the files go to the LiDAR's Output folder beside the .blend: it says so
    own = rls("scan", out, "--sensor", "LiDAR", "--frames", "1")
    assert own.returncode == 0, own.stderr
    where = tmp_path / "lidar"
    assert f"rls: notice: no --out given: LiDAR writes to {where} " in own.stderr, own.stderr
    assert (where / "Scene_LiDAR_000001.pcd").is_file()
    table = rls("lidar", "list", out)
    assert "Pole LiDAR" in table.stdout and "Livox Avia" in table.stdout, table.stdout
    gone = tmp_path / "gone.blend"
    proc = rls("lidar", "remove", out, "--sensor", "Pole LiDAR", "--out", gone)
    assert proc.returncode == 0, proc.stderr
    assert sorted(listed(gone)) == ["LiDAR"]
    assert sorted(listed(out)) == ["LiDAR", "Pole LiDAR"]


def test_bad_input_one_error_nothing_written(scene, tmp_path):
    out = tmp_path / "x.blend"
    base = ("lidar", "add", scene, "--out", out)
    cases = [
        (("--preset", "hesai_pandar64", "--mount", "Nope"), "no object named 'Nope'"),
        (("--preset", "no_such_lidar", "--mount", "Pole"), "unknown device preset"),
        (("--preset", "hesai_pandar64", "--at", "nan,0,3"), "finite"),
        (("--preset", "hesai_pandar64", "--at", "1,2"), "X,Y,Z"),
        (("--preset", "hesai_pandar64", "--at", "0,0,3", "--pitch", "120"), "between -90"),
        (("--preset", "hesai_pandar64", "--mount", "Pole", "--name", "Ground"),
         "already has an object named 'Ground'"),
    ]
    for extra, match in cases:
        line = one_line_error(rls(*base, *extra))
        assert match in line, line
        assert not out.exists()
    assert "Pole" in one_line_error(rls(*base, "--preset", "hesai_pandar64", "--mount", "Nope"))
    # an existing output, and the scene itself, only with --overwrite
    out.write_bytes(b"keep")
    line = one_line_error(rls(*base, "--preset", "hesai_pandar64", "--mount", "Pole"))
    assert "already exists" in line and out.read_bytes() == b"keep"
    before = digest(scene)
    line = one_line_error(rls("lidar", "add", scene, "--preset", "hesai_pandar64", "--mount",
                              "Pole", "--out", scene))
    assert "already exists" in line and digest(scene) == before
    line = one_line_error(rls("lidar", "add", scene, "--preset", "hesai_pandar64", "--mount",
                              "Pole", "--out", tmp_path / "x.txt"))
    assert ".blend" in line
    line = one_line_error(rls("lidar", "remove", scene, "--sensor", "Ground",
                              "--out", tmp_path / "y.blend"))
    assert "not a LiDAR" in line and not (tmp_path / "y.blend").exists()
    line = one_line_error(rls("lidar", "list", tmp_path / "missing.blend"))
    assert "not found" in line
