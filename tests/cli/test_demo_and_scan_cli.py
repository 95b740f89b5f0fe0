"""The demo and the scan command, as a user runs them."""

import json
from pathlib import Path

import numpy as np

from .conftest import one_line_error, rls


def test_demo_writes_a_cloud_open3d_reads_with_the_reported_count(demo_run):
    import open3d as o3d

    out, summary, proc = demo_run
    cloud = Path(summary["point_cloud"])
    assert cloud.is_file() and cloud.parent == out.resolve()
    assert str(cloud) in proc.stdout  # the demo says where its output is
    assert summary["points"] > 10000
    pcd = o3d.io.read_point_cloud(str(cloud))
    assert len(pcd.points) == summary["points"]
    assert Path(summary["scene"]).is_file()


def test_scan_frame_range_writes_clouds_sidecars_and_summary(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    proc = rls("scan", blend, "--sensor", "LiDAR", "--frames", "1-3:2", "--out", out,
               "--format", "ply_binary")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["frames"] == [1, 3] and summary["sensors"] == ["LiDAR"]
    names = sorted(p.name for p in out.iterdir())
    assert names == ["intersection_LiDAR_000001.json", "intersection_LiDAR_000001.ply",
                     "intersection_LiDAR_000003.json", "intersection_LiDAR_000003.ply",
                     "intersection_instances.json"]
    instances = json.loads((out / "intersection_instances.json").read_text())["instances"]
    assert {v["object"]: v["label_name"] for v in instances.values()}["Car west"] == "vehicle"
    side = json.loads((out / "intersection_LiDAR_000001.json").read_text())
    assert side["device"]["id"] == "hesai_pandar64" and side["frame"] == 1
    assert "[2/2]" in proc.stderr and "left" in proc.stderr  # per-frame progress with estimate
    # Same inputs, same bytes.
    again = tmp_path / "again"
    rls("scan", blend, "--frames", "1", "--out", again, "--format", "ply_binary")
    assert (again / "intersection_LiDAR_000001.ply").read_bytes() == \
        (out / "intersection_LiDAR_000001.ply").read_bytes()


def test_scan_refuses_to_overwrite_without_flag(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    assert rls("scan", blend, "--out", tmp_path).returncode == 0
    line = one_line_error(rls("scan", blend, "--out", tmp_path))
    assert "overwrite" in line
    assert rls("scan", blend, "--out", tmp_path, "--overwrite").returncode == 0


def test_missing_scene_file(tmp_path):
    line = one_line_error(rls("scan", tmp_path / "nope.blend", "--out", tmp_path))
    assert "scene file not found" in line and "nope.blend" in line


def test_unknown_sensor(demo_run, tmp_path):
    line = one_line_error(rls("scan", demo_run[0] / "intersection.blend", "--sensor", "Nope",
                              "--out", tmp_path))
    assert "'Nope'" in line and "LiDAR" in line


def test_unwritable_output_directory(demo_run, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    line = one_line_error(rls("scan", demo_run[0] / "intersection.blend", "--out", blocker / "sub"))
    assert "output folder" in line


def test_bad_frame_range(demo_run, tmp_path):
    line = one_line_error(rls("scan", demo_run[0] / "intersection.blend", "--frames", "9-2",
                              "--out", tmp_path))
    assert "--frames" in line


def test_scan_motion_and_ghosting_overrides(demo_run, tmp_path):
    """The sample intersection has cars driving through and a glass facade."""
    blend = demo_run[0] / "intersection.blend"
    sides = {}
    for name, extra in (("exact", []), ("snapshot", ["--motion", "snapshot"]),
                        ("noghost", ["--ghosting", "off"])):
        out = tmp_path / name
        proc = rls("scan", blend, "--frames", "5", "--out", out, *extra)
        assert proc.returncode == 0, proc.stderr
        sides[name] = json.loads((out / "intersection_LiDAR_000005.json").read_text())
    rigid = sides["exact"]["motion"]["rigid"]  # what moves: not the parked vehicles
    assert {"Car west", "Car east", "Car north", "Car south", "Pedestrian 1",
            "Cyclist 1"} < set(rigid)
    assert not [n for n in rigid if "parked" in n]
    assert sides["snapshot"]["motion"]["rigid"] == []
    assert sides["snapshot"]["effects"]["motion"] == "snapshot"
    assert sides["exact"]["ghosts"] > 0 and sides["noghost"]["ghosts"] == 0
    line = one_line_error(rls("scan", blend, "--substeps", "-1", "--out", tmp_path / "bad"))
    assert "--substeps" in line


def test_scan_backends_give_the_same_points(demo_run, tmp_path):
    """Embree and BVHTree decide only which triangle a ray hits; ranges are refined
    exactly in float64, so away from edges the clouds agree to 1e-4 m."""
    from rls_addon.core.output.io import read_cloud

    blend = demo_run[0] / "intersection.blend"
    clouds = {}
    for backend in ("bvhtree", "embree"):
        out = tmp_path / backend
        proc = rls("scan", blend, "--frames", "1", "--out", out, "--backend", backend,
                   "--ghosting", "off", "--motion", "snapshot")
        assert proc.returncode == 0, proc.stderr
        side = json.loads((out / "intersection_LiDAR_000001.json").read_text())
        assert side["backend"] == backend
        clouds[backend] = read_cloud(out / "intersection_LiDAR_000001.pcd")
    a, b = clouds["bvhtree"], clouds["embree"]
    key = lambda p: np.round(p["time"] * 1e9).astype(np.int64) * 4096 + p["ring"]  # noqa: E731
    common, ia, ib = np.intersect1d(key(a), key(b), return_indices=True)
    assert len(common) >= 0.999 * max(len(a), len(b))  # the same rays return
    dist = lambda p: np.sqrt(p["x"] ** 2 + p["y"] ** 2 + p["z"] ** 2)  # noqa: E731
    diff = np.abs(dist(a)[ia] - dist(b)[ib])
    # Rays through an edge may pick the other face: a handful, never more than 0.1%.
    assert np.quantile(diff, 0.999) <= 1e-4
