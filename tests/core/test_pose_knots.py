"""The sidecar's pose knots of a moving sensor (``motion.pose_knots``) and its start
and end poses (``session.sensor_pose_record``): the ends and their first midpoint
evaluated together, and the start and end taken from the knots where the track spans
the sweep, give the bytes of evaluating each on its own (the way it was done before),
on driving, accelerating, turning, tumbling and still tracks."""

import numpy as np
import pytest

from rls_addon.core.scan.session import sensor_pose_record
from rls_addon.core.scene.motion import KNOT_TOLERANCE_M, Track, pose_knots, poses_at, rigid

from .test_track_set import tracks, turned

PERIOD = 0.1


def pose_knots_reference(track, tolerance_m=KNOT_TOLERANCE_M, reach_m=1.0):
    """``pose_knots`` as it was: every evaluation on its own."""
    lo, hi = float(track.times[0]), float(track.times[-1])
    probe = np.array([[0, 0, 0, 1], [reach_m, 0, 0, 1], [0, reach_m, 0, 1], [0, 0, reach_m, 1]],
                     float).T
    times = np.array([lo, hi]) if hi > lo else np.array([lo])
    mats = rigid(track.at(times))
    while len(times) > 1:
        mids = (times[1:] + times[:-1]) / 2
        at_mids = rigid(track.at(mids))
        err = np.linalg.norm((poses_at(times, mats, mids) - at_mids) @ probe, axis=1)
        bad = err.max(axis=1) > tolerance_m
        if not bad.any() or len(times) >= 4097:
            break
        order = np.argsort(np.concatenate([times, mids[bad]]), kind="stable")
        times = np.concatenate([times, mids[bad]])[order]
        mats = np.concatenate([mats, at_mids[bad]])[order]
    return times, mats


def sweeps():
    """Sensor tracks sampled over a sweep (as ``sweep.sample_sweep`` samples them:
    from 0 to the period), and the test tracks of ``test_track_set``."""
    t = np.linspace(0.0, PERIOD, 9)
    out = []
    for speed, yaw_rate, accel in ((10.0, 0.0, 0.0), (10.0, 2.0, 0.0), (3.0, 8.0, 30.0),
                                   (0.0, 0.0, 0.0), (25.0, -15.0, -40.0)):
        mats = []
        for tt in t:
            m = turned(yaw_rate * tt)
            m[:3, 3] = [speed * tt + accel * tt * tt, 1.75, 1.9]
            mats.append(m)
        out.append(Track(t, mats))
    return out + tracks(np.random.default_rng(7), 30)


@pytest.mark.parametrize("k", range(35))
def test_pose_knots_are_the_reference_byte_for_byte(k):
    track = sweeps()[k]
    times, mats = pose_knots(track)
    want_t, want_m = pose_knots_reference(track)
    assert times.tobytes() == want_t.tobytes() and mats.tobytes() == want_m.tobytes()


@pytest.mark.parametrize("k", range(35))
def test_the_records_start_and_end_are_the_tracks_own(k):
    track = sweeps()[k]
    pose = rigid(track.at([0.0])[0])
    got = sensor_pose_record(pose, track, PERIOD)
    assert got["sensor_pose_start"] == rigid(track.at([0.0])[0]).tolist()
    assert got["sensor_pose_end"] == rigid(track.at([PERIOD])[0]).tolist()
