"""The sweep's sampling and classification (``scan/sweep.py``) against a per-object
reference: every body's samples stacked and checked at once must give what sampling,
checking and tracking each body on its own gives, byte for byte, on driving, turning
and accelerating tracks, a body missing from some states and a moving sensor."""

import math

import numpy as np
import pytest

from rls_addon.core.scan import sweep as sw
from rls_addon.core.scene.motion import Track
from rls_addon.core.scene.source import Mobility
from tests.core.scenes import box_vertices


def _pose(x, y, z, yaw):
    m = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = x, y, z
    return m


MOTIONS = {  # seconds -> 4x4
    "driving": lambda t: _pose(3.0 + 12.0 * t, -1.75, 0.0, 0.0),
    "turning": lambda t: _pose(8.0 * math.cos(0.6 * t), 8.0 * math.sin(0.6 * t), 0.0,
                               0.6 * t + math.pi / 2),
    "accelerating": lambda t: _pose(-4.0 + 2.0 * t + 40.0 * t * t, 5.0, 0.2, 0.3),
    "braking_turn": lambda t: _pose(10.0 * t - 30.0 * t * t, 2.0 - 3.0 * t, 0.0, 2.5 * t * t),
    "parked": lambda t: _pose(1.0, 2.0, 0.0, 0.4),
}


class _Instance:
    def __init__(self, key, vertices, matrix):
        self.key, self.vertices, self.matrix = key, vertices, matrix


class _Sweep:
    """States from ``MOTIONS`` at ``t0 + t``; ``gone`` is absent from states after
    ``gone_after`` s (its matrix then is the instance's own, as ``sample_sweep`` says)."""

    def __init__(self, t0, sensor_motion, gone=None, gone_after=0.05):
        self.t0, self.sensor_motion, self.gone, self.gone_after = t0, sensor_motion, gone, gone_after

    def state(self, t, keys, deform_keys, sensor):
        s = self.t0 + t
        mats = {k: MOTIONS[k](s) for k in keys if not (k == self.gone and t > self.gone_after)}
        return mats, {}, self.sensor_motion(s)


def _reference(sweep, period, instances, cand, sensor_moves):
    """The per-object reference: each state read as a dict, each body's interpolation
    checked on its own (``_interp_error``), each body's and the sensor's track made on
    its own (``Track``)."""
    keys = {instances[k].key: k for k in cand}
    corners = [sw.box_corners(instances[k].vertices) for k in cand]

    def rows(states):
        out = [np.array([s[0].get(instances[k].key, instances[k].matrix) for s in states])
               for k in cand]
        return out + ([np.array([s[2] for s in states])] if sensor_moves else [])

    points = corners + ([np.zeros((1, 3))] if sensor_moves else [])
    n = 5
    times = np.linspace(0.0, period, n)
    states = [sweep.state(t, keys, set(), "lidar") for t in times]
    while n < sw.MAX_SAMPLES:
        mids = (times[:-1] + times[1:]) / 2
        mid_states = [sweep.state(t, keys, set(), "lidar") for t in mids]
        worst = max((sw._interp_error(times, m, mids, p, q)
                     for m, p, q in zip(rows(states), rows(mid_states), points)), default=0.0)
        merged_t = np.empty(2 * n - 1)
        merged_t[0::2], merged_t[1::2] = times, mids
        merged = [None] * (2 * n - 1)
        merged[0::2], merged[1::2] = states, mid_states
        times, states, n = merged_t, merged, 2 * n - 1
        if worst <= sw.INTERP_TOLERANCE_M:
            break
    every = rows(states)
    rigid = [(k, Track(times, m)) for k, m in zip(cand, every)
             if np.abs(m - m[0]).max() > 1e-12]
    sensor = None
    if sensor_moves and np.abs(every[-1] - every[-1][0]).max() > 1e-12:
        sensor = Track(times, every[-1])
    return times, rigid, sensor


def _same_track(a, b):
    assert np.array_equal(a.times, b.times)
    assert np.array_equal(a.matrices, b.matrices)
    assert np.array_equal(a._quat, b._quat) and np.array_equal(a._scale, b._scale)
    assert np.array_equal(a.velocities, b.velocities)
    probe = np.linspace(-0.01, 0.11, 97)
    assert np.array_equal(a.at(probe), b.at(probe))


@pytest.mark.parametrize("t0, sensor_motion, gone", [
    (0.0, MOTIONS["driving"], None),
    (0.7, MOTIONS["turning"], "accelerating"),
    (1.3, lambda t: _pose(1.0, 1.0, 2.0, 0.0), None),      # a still sensor
    (2.1, MOTIONS["braking_turn"], "driving"),
])
def test_classify_is_the_per_object_reference(t0, sensor_motion, gone):
    names = list(MOTIONS)
    instances = [_Instance(n, box_vertices((-2.0, -1.0, 0.0), (2.0 + k, 1.0, 1.5)),
                           MOTIONS[n](t0)) for k, n in enumerate(names)]
    # the first instance (not a candidate) and the rest in a shuffled order
    cand = [4, 2, 0, 3, 1][:len(names)]
    sensor_moves = True
    mobility = Mobility(list(cand), set(), sensor_moves)
    sweep = _Sweep(t0, sensor_motion, gone)
    got = sw.classify(sweep, 0.1, instances, mobility, "lidar")
    times, rigid, sensor = _reference(sweep, 0.1, instances, cand, sensor_moves)
    assert got.samples == len(times) and np.array_equal(got.times, times)
    assert [k for k, _ in got.rigid] == [k for k, _ in rigid]
    assert "parked" not in {instances[k].key for k, _ in got.rigid}
    for (_, a), (_, b) in zip(got.rigid, rigid):
        _same_track(a, b)
    assert set(got.tracks) == {k for k, _ in rigid}
    assert (got.sensor is None) == (sensor is None)
    if sensor is not None:
        _same_track(got.sensor, sensor)


def test_accelerating_bodies_are_sampled_beyond_the_first_check():
    """The accelerating and braking-and-turning tracks need more than nine samples
    (so the doubling itself, and the merging of samples, is what is compared above)."""
    instances = [_Instance(n, box_vertices((-2.0, -1.0, 0.0), (2.0, 1.0, 1.5)), MOTIONS[n](0))
                 for n in ("accelerating", "braking_turn")]
    got = sw.classify(_Sweep(0.0, MOTIONS["driving"]), 0.1, instances,
                      Mobility([0, 1], set(), True), "lidar")
    assert got.samples > 9


def test_errors_of_many_bodies_are_each_bodys_own():
    """``_interp_errors`` (every body's distances in one product, their points padded
    to the most any has) gives each body's ``_interp_error`` exactly, with bodies of
    one, two and three points (the sensor has one) on driving, turning and
    accelerating tracks. A one-point body's point is where its error is smaller than
    at its origin, so padding it with anything but its own point would show."""
    rng = np.random.default_rng(4)
    times = np.linspace(0.0, 0.1, 5)
    mids = (times[1:] + times[:-1]) / 2

    def skid(t):  # round a tight bend, turning ever faster: errors differ point to point
        return _pose(3.0 * math.cos(6.0 * t), 3.0 * math.sin(6.0 * t), 0.0, 6.0 * t + 2.0 * t * t)

    motions = [skid, MOTIONS["turning"], MOTIONS["accelerating"], skid, MOTIONS["driving"]]
    mats = np.array([[f(1.0 + t) for t in times] for f in motions])
    probe = np.array([[f(1.0 + t) for t in mids] for f in motions])
    points = [rng.normal(0, 3, (n, 3)) for n in (1, 3, 2, 1, 2)]
    for j in (0, 3):
        cloud = rng.normal(0, 1, (200, 3))
        err = [sw._interp_error(times, mats[j], mids, probe[j], c[None]) for c in cloud]
        points[j] = cloud[int(np.argmin(err))][None]
        assert min(err) < sw._interp_error(times, mats[j], mids, probe[j], np.zeros((1, 3)))
    got = sw._interp_errors(times, mats, mids, probe, points)
    assert got == [sw._interp_error(times, m, mids, p, q)
                   for m, p, q in zip(mats, probe, points)]
    assert min(got) > 0.0
    # one body alone (a sensor over a still scene) is its own track's answer too
    assert sw._interp_errors(times, mats[2:3], mids, probe[2:3], points[2:3]) == \
        [sw._interp_error(times, mats[2], mids, probe[2], points[2])]


def test_the_sweeps_end_is_read_after_its_first_midpoints():
    """Every sample is read once, and the sweep's end (the next frame's start) after
    the first midpoints: a Blender source is left where a run goes next."""
    asked = []

    class Recording(_Sweep):
        def state(self, t, keys, deform_keys, sensor):
            asked.append(float(t))
            return super().state(t, keys, deform_keys, sensor)

    instances = [_Instance("driving", box_vertices((-2.0, -1.0, 0.0), (2.0, 1.0, 1.5)),
                           MOTIONS["driving"](0))]
    got = sw.classify(Recording(0.0, MOTIONS["turning"]), 0.1, instances,
                      Mobility([0], set(), True), "lidar")
    assert sorted(asked) == got.times.tolist() and len(set(asked)) == len(asked)
    first = np.linspace(0.0, 0.1, 5)
    assert asked[:8] == first[:-1].tolist() + ((first[1:] + first[:-1]) / 2).tolist()
    assert asked[8] == 0.1
