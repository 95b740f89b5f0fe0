"""rls scan's point types, LAS and ROS 2 bags, each read back by a reader that is not ours:
PCL's typed PCD loader with each driver's point struct, laspy and lazpy, the MCAP
reference reader. Every file is compared with the same frame written in RLS's own
lossless point type (same seed, so the same points)."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from rls_addon.core.output.io import pcd
from tests.core import pcl_typed
from tests.core.external_tools import require_module

from .conftest import ROOT, one_line_error, rls

START = 1_700_000_000.25  # --start-time: Unix seconds of frame 1
ALL = "intensity,ring,time,label,instance,ghost,range"


def scan(blend, out, *args):
    proc = rls("scan", blend, "--sensor", "LiDAR", "--frames", "1", "--out", out,
               "--workers", "1", *args)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def reference(demo_run, tmp_path_factory):
    """Frame 1 in RLS's point type with every field, in the sensor and in the world frame."""
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path_factory.mktemp("rls")
    scan(blend, out / "sensor", "--point-type", "rls", "--fields", ALL, "--frame-space", "sensor")
    scan(blend, out / "world", "--point-type", "rls", "--fields", ALL, "--frame-space", "world")
    sensor = pcd.decode((out / "sensor" / "intersection_LiDAR_000001.pcd").read_bytes())
    world = pcd.decode((out / "world" / "intersection_LiDAR_000001.pcd").read_bytes())
    side = json.loads((out / "sensor" / "intersection_LiDAR_000001.json").read_text())
    assert len(sensor) == len(world) == side["points"] > 10000
    return blend, sensor, world, side


@pytest.fixture(scope="module")
def pcl_reader(tmp_path_factory):
    return pcl_typed.build(tmp_path_factory.mktemp("pcl_typed"))


def elevation_by_ring(rows, xyz_cols, ring_col):
    """Mean elevation (degrees) of the points of each ring, rings in increasing order."""
    xyz = rows[:, xyz_cols]
    el = np.degrees(np.arcsin(xyz[:, 2] / np.linalg.norm(xyz, axis=1)))
    rings = rows[:, ring_col].astype(int)
    return [el[rings == r].mean() for r in np.unique(rings)]


def one_to_one(a, b):
    """Each value of ``a`` goes with exactly one of ``b`` and back."""
    pairs = set(zip(a.astype(int).tolist(), b.astype(int).tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


@pytest.mark.parametrize("name", ["velodyne", "ouster", "hesai", "autoware"])
def test_driver_point_types_read_by_pcl_typed_loader(reference, pcl_reader, tmp_path, name):
    blend, ref, _, side = reference
    scan(blend, tmp_path, "--point-type", name, "--start-time", str(START))
    path = tmp_path / "intersection_LiDAR_000001.pcd"
    got = pcl_typed.read(pcl_reader, name, path)
    names = list(pcd.decode(path.read_bytes()).dtype.names)
    col = {f: names.index(f) for f in names}
    assert got.shape == (len(ref), len(names))
    for axis in "xyz":  # the same points, float32 as in RLS's files
        np.testing.assert_array_equal(got[:, col[axis]], ref[axis].astype(np.float64), err_msg=axis)
    channels = side["device"].get("channels") or len(np.unique(ref["ring"]))
    time = ref["time"]
    assert np.ptp(time) > 0.05  # a real sweep: 0.1 s at 10 Hz
    if name == "velodyne":
        np.testing.assert_array_equal(got[:, col["time"]], time.astype(np.float32))
        # only the first firing is at 0, as in RLS's own file (not 0 everywhere)
        assert np.count_nonzero(got[:, col["time"]]) == np.count_nonzero(time) > len(ref) // 2
        np.testing.assert_allclose(got[:, col["intensity"]], ref["intensity"] * 255.0, atol=0.5 + 1e-3)
        # rings by elevation, lowest beam = 0 (velodyne_pointcloud's numbering)
        el = elevation_by_ring(got, [col["x"], col["y"], col["z"]], col["ring"])
        assert np.all(np.diff(el) > 0), el
    elif name == "ouster":
        t = got[:, col["t"]]
        assert np.abs(t - np.round(time * 1e9)).max() <= 1  # uint32 ns since sweep start
        assert t.max() < 2**32 and np.count_nonzero(t) == np.count_nonzero(time) > len(ref) // 2
        # mm, rounded from the float64 range; the reference is float32 (0.007 mm at 120 m)
        assert np.abs(got[:, col["range"]] - ref["range"] * 1000.0).max() <= 0.5 + 0.01
        el = elevation_by_ring(got, [col["x"], col["y"], col["z"]], col["ring"])
        assert np.all(np.diff(el) < 0), el  # 0 = top beam (ouster-ros)
    elif name == "hesai":
        stamp = got[:, col["timestamp"]]
        assert np.abs(stamp - (START + time)).max() < 2e-6  # absolute, microseconds kept
        np.testing.assert_array_equal(got[:, col["ring"]], ref["ring"])  # the table row
    else:
        assert set(np.unique(got[:, col["return_type"]])) == {1}  # single strongest
        np.testing.assert_array_equal(got[:, col["channel"]], ref["ring"])
        assert got[:, col["intensity"]].max() <= 255
        np.testing.assert_allclose(got[:, col["intensity"]], ref["intensity"] * 255.0, atol=0.5 + 1e-3)
    ring = col.get("ring", col.get("channel"))
    assert one_to_one(got[:, ring], ref["ring"])
    assert got[:, ring].min() >= 0 and got[:, ring].max() < channels


def test_las_read_by_laspy_and_lazpy(reference, tmp_path):
    laspy = require_module("laspy", "laspy==2.7.0")
    lazpy = require_module("lazpy", "lazpy==0.9.2")
    blend, _, world, side = reference
    summary = scan(blend, tmp_path, "--format", "las", "--crs", "EPSG:25832",
                   "--start-time", str(START), "--fields", ALL)
    path = tmp_path / "intersection_LiDAR_000001.las"
    assert summary["outputs"][0]["file"] == str(path)
    las = laspy.read(str(path))
    h = las.header
    assert (h.version.major, h.version.minor) == (1, 4) and h.point_count == len(world)
    assert h.parse_crs().to_epsg() == 25832
    xyz = np.stack([las.x, las.y, las.z], axis=1)
    want = np.stack([world["x"], world["y"], world["z"]], axis=1).astype(np.float64)
    # world float32 in the reference file: about 1e-6 m here; LAS keeps 0.1 mm steps
    np.testing.assert_allclose(xyz, want, rtol=0, atol=6e-5)
    np.testing.assert_array_equal(np.asarray(las["ring"]), world["ring"])
    np.testing.assert_array_equal(np.asarray(las["instance"]), world["instance"])
    np.testing.assert_array_equal(np.asarray(las["label"]), world["label"])
    # GPS times: one sweep (0.1 s) starting at the run's start time
    gps = np.asarray(las.gps_time)
    assert np.ptp(gps) == pytest.approx(np.ptp(world["time"]), abs=1e-6)
    assert int(h.global_encoding.gps_time_type) == 1  # adjusted standard GPS time
    adjusted = START - 315964800 + 18 - 1e9  # Unix -> GPS (18 leap seconds) - 1e9
    assert gps.min() == pytest.approx(adjusted + world["time"].min(), abs=1e-6)
    # ASPRS classes (LAS 1.4 R15): road -> 11 Road Surface, sidewalk -> 2 Ground,
    # building -> 6; labels without a standard class -> user-definable 64 + label
    cls = np.asarray(las.classification)
    for label, asprs in ((1, 11), (2, 2), (3, 6), (11, 64 + 11)):
        on = world["label"] == label
        assert on.any(), label  # the sample intersection has roads, sidewalks, houses and cars
        assert set(np.unique(cls[on])) == {asprs}, label
    r = lazpy.Reader(str(path))
    assert r.num_points == len(world)
    a = r.arrays()
    xyz2 = np.stack([a["X"], a["Y"], a["Z"]], axis=1) * np.array(r.scales) + np.array(r.offsets)
    np.testing.assert_allclose(xyz2, xyz, rtol=0, atol=1e-9)
    assert side["points"] == len(world)


def test_ros2_bag_read_by_mcap_reader(reference, tmp_path):
    mcap_reader = require_module("mcap.reader", "mcap==1.6.0")
    decoder = require_module("mcap_ros2.decoder", "mcap-ros2-support==0.6.0")
    blend, ref, _, side = reference
    fps = side["frame_rate_hz"]  # the scene's frame rate (the street's: 24)
    proc = rls("scan", blend, "--sensor", "LiDAR", "--frames", "1-3", "--out", tmp_path,
               "--format", "mcap", "--point-type", "velodyne", "--start-time", str(START),
               "--workers", "1")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    bag = tmp_path / "intersection_rosbag2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["intersection_rosbag2"]
    assert sorted(p.name for p in bag.iterdir()) == ["intersection_rosbag2.mcap", "metadata.yaml"]
    with open(bag / "intersection_rosbag2.mcap", "rb") as fh:
        reader = mcap_reader.make_reader(fh, decoder_factories=[decoder.DecoderFactory()])
        msgs = [(ch.topic, m.log_time, ros) for _, ch, m, ros in reader.iter_decoded_messages()]
    clouds = [(ns, m) for t, ns, m in msgs if t.endswith("/points")]
    assert [m.width for _, m in clouds] == [o["points"] for o in summary["outputs"]]
    assert clouds[0][1].width == len(ref)
    start_ns = 1_700_000_000_250_000_000  # START exactly, not START * 1e9 in float64
    for k, (ns, m) in enumerate(clouds):
        want = start_ns + round(k * 1e9 / fps)
        assert ns == want == m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        assert [f.name for f in m.fields] == ["x", "y", "z", "intensity", "ring", "time"]
    first = clouds[0][1]
    kinds = {2: "u1", 4: "<u2", 7: "<f4", 8: "<f8"}
    dt = np.dtype({"names": [f.name for f in first.fields],
                   "formats": [kinds[f.datatype] for f in first.fields],
                   "offsets": [f.offset for f in first.fields], "itemsize": first.point_step})
    pts = np.frombuffer(bytes(first.data), dtype=dt)
    np.testing.assert_array_equal(pts["x"], ref["x"])
    np.testing.assert_array_equal(pts["time"], ref["time"].astype(np.float32))
    frame_id = first.header.frame_id
    static = [m for t, _, m in msgs if t == "/tf_static"]
    assert static and static[0].transforms[0].child_frame_id == frame_id  # a pole: static TF
    q = static[0].transforms[0].transform.rotation
    assert math.isclose(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2, 1.0, abs_tol=1e-9)


def test_bag_refuses_world_frame_and_writes_nothing(reference, tmp_path):
    blend = reference[0]
    line = one_line_error(rls("scan", blend, "--frames", "1", "--out", tmp_path, "--format",
                              "mcap", "--frame-space", "world", "--workers", "1"))
    assert "sensor-frame" in line and "--frame-space sensor" in line
    assert list(tmp_path.iterdir()) == []  # nothing written


# ``python -m rls_addon`` with the bag's MCAP file on a full disk (/dev/full): every
# write to it fails with ENOSPC, as on a disk that filled up during a run.
FULL_DISK = r"""
import os, pathlib, runpy, sys
real = pathlib.Path.open
def full(self, mode="r", *args, **kwargs):
    if self.suffix == ".mcap" and ("w" in mode or "x" in mode):
        return open("/dev/full", "wb")
    return real(self, mode, *args, **kwargs)
pathlib.Path.open = full
sys.argv = ["rls", *sys.argv[1:]]
runpy.run_module("rls_addon", run_name="__main__", alter_sys=True)
"""


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_bag_on_a_full_disk_is_one_line_and_leaves_nothing(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", FULL_DISK, "scan", str(blend), "--frames",
                           "1-2", "--out", str(tmp_path), "--format", "mcap", "--workers", "1"],
                          env=env, capture_output=True, text=True, timeout=600)
    bag = tmp_path / "intersection_rosbag2"
    assert one_line_error(proc).startswith(f"rls: error: cannot write bag {bag}: No space "
                                           "left on device")
    assert proc.returncode == 1
    assert list(tmp_path.iterdir()) == []  # no bag, no temporary folder


def test_a_start_time_that_is_not_finite_is_one_line(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    for fmt, value in (("las", "inf"), ("mcap", "nan"), ("pcd_binary", "inf")):
        proc = rls("scan", blend, "--frames", "1", "--out", tmp_path, "--format", fmt,
                   "--start-time", value, "--workers", "1")
        assert one_line_error(proc) == ("rls: error: the start time (start_time_s, s) must be "
                                        f"a finite number, got {float(value)!r}")
        assert proc.returncode == 1 and list(tmp_path.iterdir()) == []


def test_a_las_date_beyond_year_9999_is_one_line(demo_run, tmp_path):
    proc = rls("scan", demo_run[0] / "intersection.blend", "--frames", "1", "--out", tmp_path,
               "--format", "las", "--start-time", "1e300", "--workers", "1")
    assert one_line_error(proc).startswith("rls: error: cannot write ")
    assert "beyond the dates a LAS header holds (years 1 to 9999)" in proc.stderr
    assert proc.returncode == 1


def test_a_bag_stamp_before_1970_is_one_line_and_writes_nothing(demo_run, tmp_path):
    proc = rls("scan", demo_run[0] / "intersection.blend", "--frames", "1", "--out", tmp_path,
               "--format", "mcap", "--start-time=-5", "--workers", "1")
    assert one_line_error(proc) == (
        "rls: error: a ROS 2 bag's stamps are unsigned nanoseconds, from 0 (1970) to "
        "18446744073.709551615 s: frame 1 would be stamped -5 s; give a start time "
        "(--start-time) that puts every frame in that span")
    assert proc.returncode == 1 and list(tmp_path.iterdir()) == []
