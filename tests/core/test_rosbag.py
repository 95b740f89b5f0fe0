"""ROS 2 bags written with rosbags, read back with a different library: the MCAP
reference reader (``mcap``) and its ROS 2 decoder (``mcap-ros2-support``)."""

import sys

import numpy as np
import pytest

from rls_addon.core.errors import OutputError, RLSError, SettingsError
from rls_addon.core.output.io.point_types import (
    POINT_TYPES,
    point_type_dtype,
    to_point_type,
)
from rls_addon.core.output.io.rosbag import BagWriter, frame_stamp_ns, quaternion, ros_name

from .cloud_samples import sample_cloud
from .external_tools import require_module

START = 1_700_000_000.125
START_NS = 1_700_000_000_125_000_000
FPS = 10.0
FRAMES = (1, 2, 3)  # the scene's first frame is 1


def pose(yaw, t):
    c, s = np.cos(yaw), np.sin(yaw)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = t
    return m


def tilted(t, a=0.3, b=-0.5, g=2.9):
    """A pose with roll ``a``, pitch ``b`` and yaw ``g`` (rad): every quaternion component."""
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    m = pose(g, t)
    m[:3, :3] = m[:3, :3] @ ry @ rx
    return m


def run_frames():
    """(sensor, frame, stamp_ns, points, pose, moving): a still pole lidar (tilted) and a
    lidar on a car driving +x at 10 m/s; the pole sees nothing in the last frame."""
    out = []
    for k, f in enumerate(FRAMES):
        stamp = frame_stamp_ns(START, f, FRAMES[0], FPS)
        n = 0 if f == 3 else 700 + 50 * k
        out.append(("pole.001", f, stamp, sample_cloud(n, seed=10 + k),
                    tilted((3.0, -2.0, 5.5)), False))
        out.append(("car", f, stamp, sample_cloud(400, seed=20 + k),
                    tilted((1.0 * k, 0.0, 1.8), 0.02 * k - 0.01, 0.03, 0.1 * k), True))
    return out


def read_bag(bag_dir):
    """Every message of the bag's MCAP file, decoded by mcap-ros2-support: a list of
    (topic, log_time_ns, message) and the channels' metadata by topic."""
    mcap_reader = require_module("mcap.reader", "mcap==1.6.0")
    decoder = require_module("mcap_ros2.decoder", "mcap-ros2-support==0.6.0")
    files = sorted(bag_dir.glob("*.mcap"))
    assert [f.name for f in files] == [f"{bag_dir.name}.mcap"]
    with open(files[0], "rb") as fh:
        reader = mcap_reader.make_reader(fh, decoder_factories=[decoder.DecoderFactory()])
        summary = reader.get_summary()
        channels = {c.topic: (summary.schemas[c.schema_id], c) for c in summary.channels.values()}
        msgs = [(ch.topic, m.log_time, ros) for _, ch, m, ros in reader.iter_decoded_messages()]
    return msgs, channels


def cloud_records(msg):
    """The PointCloud2's points as a structured array built from its own PointFields."""
    kinds = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}
    dt = np.dtype({"names": [f.name for f in msg.fields],
                   "formats": [kinds[f.datatype] for f in msg.fields],
                   "offsets": [f.offset for f in msg.fields], "itemsize": msg.point_step})
    assert not msg.is_bigendian and msg.height == 1
    assert msg.row_step == msg.width * msg.point_step == len(bytes(msg.data))
    return np.frombuffer(bytes(msg.data), dtype=dt, count=msg.width)


def matrix(tf):
    q = tf.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = [tf.translation.x, tf.translation.y, tf.translation.z]
    return m


@pytest.mark.parametrize("name", POINT_TYPES)
def test_every_point_and_stamp_reads_back(tmp_path, name):
    frames = run_frames()
    bag = tmp_path / "run"
    with BagWriter(bag, point_type=name, world_frame="map") as w:
        for sensor, f, stamp, pts, m, moving in frames:
            w.write(sensor, f, stamp, pts, m, moving)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary left
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "run.mcap"]
    msgs, channels = read_bag(bag)

    assert {t: s.name for t, (s, _) in channels.items()} == {
        "/pole_001/points": "sensor_msgs/msg/PointCloud2", "/car/points": "sensor_msgs/msg/PointCloud2",
        "/tf": "tf2_msgs/msg/TFMessage", "/tf_static": "tf2_msgs/msg/TFMessage"}
    assert "transient_local" in channels["/tf_static"][1].metadata["offered_qos_profiles"]

    clouds = [(t, ns, m) for t, ns, m in msgs if t.endswith("/points")]
    assert len(clouds) == len(frames)
    for (sensor, f, stamp, pts, _, _), (topic, log_ns, msg) in zip(frames, clouds):
        assert topic == f"/{ros_name(sensor)}/points" and msg.header.frame_id == ros_name(sensor)
        want_ns = START_NS + (f - 1) * 100_000_000  # 10 frames per second
        assert stamp == want_ns == log_ns
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == want_ns
        got = cloud_records(msg)
        assert msg.width == len(pts) and msg.is_dense
        assert got.dtype.names == point_type_dtype(name).names
        want = to_point_type(pts, name, start_time_s=want_ns * 1e-9)
        for field in want.dtype.names:
            np.testing.assert_array_equal(got[field], want[field], err_msg=field)

    static = [m for t, _, m in msgs if t == "/tf_static"]
    assert len(static) == 1 and len(static[0].transforms) == 1
    tf = static[0].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("map", "pole_001")
    np.testing.assert_allclose(matrix(tf.transform), tilted((3.0, -2.0, 5.5)), atol=1e-12)
    moving = [(ns, m) for t, ns, m in msgs if t == "/tf"]
    car = [fr for fr in frames if fr[0] == "car"]
    assert len(moving) == len(car)
    for (ns, m), (_, _, stamp, _, want_pose, _) in zip(moving, car):
        (tf,) = m.transforms
        assert tf.child_frame_id == "car" and ns == stamp
        assert tf.header.stamp.sec * 1_000_000_000 + tf.header.stamp.nanosec == stamp
        np.testing.assert_allclose(matrix(tf.transform), want_pose, atol=1e-12)


def test_records_already_in_the_point_type_are_written_as_they_are(tmp_path):
    pts = sample_cloud(300, seed=4)
    rec = to_point_type(pts, "hesai", start_time_s=42.0)  # the caller's own start time
    with BagWriter(tmp_path / "b", point_type="hesai") as w:
        w.write("s", 0, 5_000_000_000, rec, np.eye(4), False)
    (_, _, msg), = [m for m in read_bag(tmp_path / "b")[0] if m[0] == "/s/points"]
    np.testing.assert_array_equal(cloud_records(msg)["timestamp"], rec["timestamp"])


def test_static_transforms_accumulate_for_late_subscribers(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        w.write("a", 0, 1_000, sample_cloud(5), pose(0.0, (1, 0, 0)), False)
        w.write("b", 0, 1_000, sample_cloud(5), pose(0.5, (0, 1, 0)), False)
        w.write("a", 1, 2_000, sample_cloud(5), pose(0.0, (1, 0, 0)), False)
    static = [m for t, _, m in read_bag(tmp_path / "b")[0] if t == "/tf_static"]
    assert [sorted(tf.child_frame_id for tf in m.transforms) for m in static] == [["a"], ["a", "b"]]


def test_an_exception_leaves_no_bag(tmp_path):
    with pytest.raises(RuntimeError), BagWriter(tmp_path / "b") as w:
        w.write("a", 0, 1_000, sample_cloud(50), np.eye(4), False)
        raise RuntimeError("scan failed")
    assert list(tmp_path.iterdir()) == []
    w = BagWriter(tmp_path / "c")
    w.write("a", 0, 1_000, sample_cloud(50), np.eye(4), False)
    w.abort()
    assert list(tmp_path.iterdir()) == []


def test_inconsistent_frames_abort_the_bag(tmp_path):
    w = BagWriter(tmp_path / "b")
    w.write("a", 0, 1_000, sample_cloud(5), np.eye(4), False)
    with pytest.raises(OutputError, match="pose changed"):
        w.write("a", 1, 2_000, sample_cloud(5), pose(0.2, (0, 0, 0)), False)
    assert list(tmp_path.iterdir()) == []
    w = BagWriter(tmp_path / "c")
    with pytest.raises(OutputError, match="no scale"):
        w.write("a", 0, 1_000, sample_cloud(5), np.diag([2.0, 2.0, 2.0, 1.0]), True)
    w = BagWriter(tmp_path / "d", point_type="velodyne")
    with pytest.raises(OutputError, match="point type 'velodyne'"):
        w.write("a", 0, 1_000, to_point_type(sample_cloud(5), "ouster"), np.eye(4), True)
    w = BagWriter(tmp_path / "e")
    w.write("a", 0, 1_000, sample_cloud(5), np.eye(4), True)
    with pytest.raises(OutputError, match="moving in some frames"):
        w.write("a", 1, 2_000, sample_cloud(5), np.eye(4), False)
    assert list(tmp_path.iterdir()) == []


def test_existing_bag_is_kept_unless_overwrite(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        w.write("a", 0, 1_000, sample_cloud(5), np.eye(4), False)
    with pytest.raises(OutputError, match="already exists"):
        BagWriter(tmp_path / "b")
    with BagWriter(tmp_path / "b", overwrite=True) as w:
        w.write("a", 0, 1_000, sample_cloud(7), np.eye(4), False)
    (_, _, msg), = [m for m in read_bag(tmp_path / "b")[0] if m[0] == "/a/points"]
    assert msg.width == 7
    with pytest.raises(RuntimeError), BagWriter(tmp_path / "b", overwrite=True):
        raise RuntimeError("interrupted")
    (_, _, msg), = [m for m in read_bag(tmp_path / "b")[0] if m[0] == "/a/points"]
    assert msg.width == 7 and sorted(p.name for p in tmp_path.iterdir()) == ["b"]


def test_stamps_names_and_quaternions():
    assert frame_stamp_ns(START, 11, 1, 10.0) == 1_700_000_001_125_000_000
    assert frame_stamp_ns(0.0, 2, 0, 30.0) == 66_666_667
    assert frame_stamp_ns(1_700_000_000.1, 0, 0, 30.0) == 1_700_000_000_100_000_000
    assert frame_stamp_ns(0.0, 1, 0, 29.97) == 33_366_700
    with pytest.raises(SettingsError):
        frame_stamp_ns(0.0, 1, 0, 0.0)
    assert ros_name("pole.001") == "pole_001" and ros_name("3d lidar") == "_3d_lidar"
    assert ros_name("roof -- left") == "roof_left"
    for m in (np.eye(4), pose(np.pi, (0, 0, 0)), tilted((0, 0, 0)), pose(-2.0, (0, 0, 0)),
              tilted((0, 0, 0), 0.2, 0.1, 0.3), tilted((0, 0, 0), 2.5, 0.2, 0.1),
              tilted((0, 0, 0), 0.1, 2.8, 0.2), tilted((0, 0, 0), 0.1, 0.2, -2.9)):
        q = quaternion(m[:3, :3])
        assert q[3] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-15

        class T:  # matrix() takes a Transform-like object
            rotation = type("Q", (), dict(zip("xyzw", q)))
            translation = type("V", (), {"x": 0.0, "y": 0.0, "z": 0.0})
        np.testing.assert_allclose(matrix(T)[:3, :3], m[:3, :3], atol=1e-14)


def test_missing_rosbags_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)
    with pytest.raises(RLSError, match="pip install rosbags"):
        BagWriter(tmp_path / "b")
    assert list(tmp_path.iterdir()) == []
