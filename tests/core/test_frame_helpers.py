"""Small helpers on a frame's hot path give what the plain numpy they replace gives."""

import numpy as np

from rls_addon.core.scan.frame import sensor_axes
from rls_addon.core.scene.geometry import hit_body, pair_rows
from rls_addon.core.scene.motion import polar


def test_hit_body_is_zero_on_hits_and_minus_one_on_misses():
    tri = np.array([5, -1, 0, 123456789012, -1, -7], np.int64)
    got = hit_body(tri)
    assert got.dtype == np.int64 and got.tolist() == np.where(tri >= 0, 0, -1).tolist()
    small = np.array([5, -1, 0, 2**31 - 1, -2**31], np.int32)
    assert hit_body(small).tolist() == [0, -1, 0, 0, -1]


def test_pair_rows_is_take_including_negative_rows():
    rng = np.random.default_rng(0)
    table = rng.integers(-2**31, 2**31 - 1, (1000, 2)).astype(np.int32)
    rows = np.concatenate([rng.integers(0, 1000, 5000), [-1, -1000, 999, 0]])
    got = pair_rows(table, rows)
    want = table.take(rows, axis=0)
    assert got.dtype == want.dtype and got.shape == want.shape
    assert np.array_equal(got, want) and got.flags.writeable
    # a table it cannot view as 8-byte rows goes through take
    wide = table.astype(np.int64)
    assert np.array_equal(pair_rows(wide, rows), wide.take(rows, axis=0))
    assert np.array_equal(pair_rows(table[:, ::-1], rows), table[:, ::-1].take(rows, axis=0))


def test_sensor_axes_kept_for_a_pose_give_the_same_bits_and_fresh_arrays():
    pose = np.eye(4)
    pose[:3, :3] = polar(np.array([[[0.9, -0.4, 0.1], [0.4, 0.9, 0.0], [0.0, 0.1, 1.1]]]))[0][0] * 1.5
    pose[:3, 3] = (1.0, 2.0, 3.0)
    first = sensor_axes(pose)
    first[0][:] = 0.0  # the caller's copy: the kept answer is not touched
    first[1][:] = 0.0
    again = sensor_axes(pose.copy())
    want = polar(pose[None, :3, :3])[0][0]
    assert np.array_equal(again[0], [1.0, 2.0, 3.0])
    assert np.array_equal(again[1].view(np.uint8), want.view(np.uint8))
    stack = sensor_axes(np.stack([pose, np.eye(4)]))
    assert stack[1].shape == (2, 3, 3) and np.array_equal(stack[1][0], want)


def _box_scan(origin, **settings):
    from rls_addon.core.casting import NumpyCaster
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.device.patterns.spinning import spinning_pattern
    from rls_addon.core.device.presets import DevicePreset, RangeModel
    from rls_addon.core.scan.settings import ScanSettings
    from tests.core.scenes import box_geometry

    preset = DevicePreset(id="t", name="t", family="spinning", source="test",
                          frequency_hz=10.0, range=RangeModel(0.1, 100.0, 0.0))
    box = box_geometry((-4.0, -4.0, -2.0), (4.0, 4.0, 2.0), label=11, instance=1, name="van")
    pose = np.eye(4)
    pose[:3, 3] = origin
    pattern = spinning_pattern(np.linspace(-30, 30, 16), 10.0, 16 * 360 * 10)
    return scan_frame(box, pattern, pose, preset,
                      ScanSettings(noise=False, dropout=False, **settings), NumpyCaster)


def test_a_sensor_inside_a_solid_object_is_warned_about_and_one_outside_is_not():
    inside = _box_scan((0.0, 0.0, 0.0))
    assert any("the sensor is inside 'van'" in w and "100%" in w for w in inside.warnings)
    outside = _box_scan((12.0, 0.0, 0.0))
    assert len(outside.points) > 100 and not any("inside" in w for w in outside.warnings)


def test_false_returns_from_the_air_do_not_count_as_hits_on_the_object():
    """In thick fog inside the box, the air's false returns are left out of the object's
    hits: all its real hits are still on the back of its faces (counted with the air's,
    they would be a minority of the points, and nothing would be said)."""
    res = _box_scan((0.0, 0.0, 0.0), weather="fog:visibility=20")
    real = len(res.points) - res.stats["weather_returns"]
    assert res.stats["weather_returns"] > 2 * real > 200
    assert any(f"100% of its {real} hits" in w for w in res.warnings)


def test_a_driving_sensors_poses_are_its_positions_at_its_distinct_times():
    """A driving sensor's rays carry their origins (its position at each ray's time);
    the distinct poses, made only when asked for, are its positions at the distinct
    firing times in time order, as before, in firing order or not."""
    from rls_addon.core.scan.aim import _DistinctPoses, distinct_times, first_of_each
    from rls_addon.core.scene.motion import Track

    times = np.linspace(0.0, 0.1, 5)
    mats = np.repeat(np.eye(4)[None], 5, axis=0)
    mats[:, 0, 3] = 3.0 + 12.0 * times + 20 * times ** 2
    track = Track(times, mats)
    rng = np.random.default_rng(2)
    for t in (np.repeat(np.linspace(0.0, 0.1, 300), 4), rng.choice(np.linspace(0, 0.1, 50), 900)):
        distinct, at = distinct_times(t)
        assert np.array_equal(t[first_of_each(t)], distinct)
        got = _DistinctPoses(track.positions_at(t), t)()
        assert np.array_equal(got, track.positions_at(distinct))
