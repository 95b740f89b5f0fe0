"""Many tracks evaluated at once (``TrackSet``) give what each ``Track`` gives on its
own, byte for byte: driving, accelerating, turning, scaled and sheared, still and
one-knot tracks, at times inside, on and beyond their knots."""

import numpy as np

from rls_addon.core.scene.motion import Track
from rls_addon.core.scene.track_set import TrackSet


def turned(yaw, pitch=0.0):
    c, s = np.cos(yaw), np.sin(yaw)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    cp, sp = np.cos(pitch), np.sin(pitch)
    r = np.eye(4)
    r[[0, 0, 2, 2], [0, 2, 0, 2]] = [cp, sp, -sp, cp]
    return m @ r


def tracks(rng, count=50):
    out = []
    for k in range(count):
        n = int(rng.integers(1, 12))
        t = np.sort(rng.uniform(0.0, 0.1, n))
        t[0] = 0.0
        kind = k % 6
        mats = []
        for tt in t:
            if kind == 0:    # driving straight
                m = np.eye(4)
                m[:3, 3] = [10 * tt, 2, 0]
            elif kind == 1:  # accelerating through a turn
                m = turned(3 * tt)
                m[:3, 3] = [5 * tt + 20 * tt * tt, 1, 0]
            elif kind == 2:  # parked
                m = turned(0.3)
                m[:3, 3] = [1, 2, 3]
            elif kind == 3:  # tumbling, scaled and sheared
                m = turned(rng.uniform(-3, 3), rng.uniform(-1, 1))
                m[:3, :3] = m[:3, :3] @ (np.eye(3) + rng.normal(0, 0.3, (3, 3)))
                m[:3, 3] = rng.normal(size=3)
            elif kind == 4:  # on a circle
                m = turned(-20 * tt)
                m[:3, 3] = [np.cos(20 * tt), np.sin(20 * tt), 0]
            else:            # mirrored
                m = turned(2 * tt) @ np.diag([1.0, -1.0, 1.0, 1.0])
                m[:3, 3] = [tt, -tt, 0]
            mats.append(m)
        out.append(Track(t, np.array(mats)))
    return out


def test_a_set_evaluates_every_track_as_the_track_does():
    rng = np.random.default_rng(1)
    ts = tracks(rng)
    both = TrackSet(ts)
    which = rng.integers(0, len(ts), 4000)
    t = rng.uniform(-0.02, 0.12, 4000)
    t[::7] = 0.0
    t[1::11] = 0.1
    t[2::13] = [ts[w].times[-1] for w in which[2::13]]  # on their last knot
    got, pos = both.at(which, t), both.positions_at(which, t)
    for r in range(len(t)):
        track = ts[which[r]]
        assert np.array_equal(track.at([t[r]])[0], got[r])
        assert np.array_equal(track.positions_at([t[r]])[0], pos[r])


def test_many_times_of_one_track_match_its_own_broadcast_evaluation():
    track = tracks(np.random.default_rng(2), 2)[1]
    t = np.linspace(0.0, 0.1, 20000)
    one = TrackSet([track])
    assert np.array_equal(track.at(t), one.at(np.zeros(len(t), int), t))
    assert np.array_equal(track.positions_at(t), one.positions_at(np.zeros(len(t), int), t))


def test_fixed_tracks_stand_for_objects_that_did_not_move():
    m = turned(0.7)
    m[:3, 3] = [4, 5, 6]
    moving = tracks(np.random.default_rng(3), 2)[1]
    both = TrackSet.of([None, moving], [m, np.eye(4)])
    assert np.array_equal(both.at([0, 0], [0.0, 0.05]), np.stack([m, m]))
    assert np.array_equal(both.at([1], [0.05])[0], moving.at([0.05])[0])


def test_still_tracks_in_a_set_are_not_decomposed():
    """A box's track of an object that stood still (``TrackSet.of``: a one-knot track
    a frame, for every parked car) is not decomposed into rotations and scales: a
    still row answers its first matrix, so they are never read. The set answers as
    before, and a track asked for its decomposition later gets the one it always had
    (``polar``, then each quaternion on the side of the one before)."""
    from rls_addon.core.scene.motion import polar, quat_from_matrix

    m = turned(0.7) @ np.diag([1.0, -2.0, 1.0, 1.0])
    m[:3, 3] = [4, 5, 6]
    parked = Track(np.array([0.0, 0.05, 0.1]), np.stack([m, m, m]))
    moving = tracks(np.random.default_rng(4), 2)[1]
    both = TrackSet.of([None, moving, parked], [m, np.eye(4), np.eye(4)])
    fixed = both.tracks[0]
    assert "_quat" not in vars(fixed) and "_scale" not in vars(fixed)
    assert "_quat" not in vars(parked) and "_scale" not in vars(parked)
    got = both.at([0, 1, 2, 2], [0.0, 0.05, 0.02, 0.1])
    assert np.array_equal(got[0], m) and np.array_equal(got[2], m) and np.array_equal(got[3], m)
    assert np.array_equal(got[1], moving.at([0.05])[0])
    for track in tracks(np.random.default_rng(5), 12) + [fixed, parked]:
        rot, scale = polar(track.matrices[:, :3, :3])
        quat = quat_from_matrix(rot)
        for k in range(1, len(quat)):
            if np.dot(quat[k - 1], quat[k]) < 0:
                quat[k] = -quat[k]
        fresh = Track(track.times, track.matrices)
        assert np.array_equal(fresh._scale, scale) and np.array_equal(fresh._quat, quat)
        fresh = Track(track.times, track.matrices)
        assert np.array_equal(fresh._quat, quat) and np.array_equal(fresh._scale, scale)


def test_a_frames_ray_origins_in_c_are_the_tracks_own():
    """A moving sensor's position at each ray's time (``track_set.positions_at``: in C
    where built) equals ``Track.positions_at`` byte for byte: driving, accelerating,
    turning and mirrored tracks, times repeated (a firing's channels), out of order,
    on knots and beyond the sweep."""
    from rls_addon.core.scene import track_set

    assert track_set.TRACK_POSITIONS.get() is not None  # the library is built here
    rng = np.random.default_rng(6)
    for track in tracks(rng, 12):
        t = np.repeat(np.linspace(-0.01, 0.11, 4000), 3)
        t[::97] = rng.uniform(-0.02, 0.12, len(t[::97]))
        t[5::101] = track.times[rng.integers(0, len(track.times), len(t[5::101]))]
        assert np.array_equal(track_set.positions_at(track, t), track.positions_at(t))


def test_tracks_made_together_are_each_tracks_own():
    """``Track.many`` (a sweep's bodies decomposed together) gives each body the track
    ``Track`` gives it: the same rotations' quaternions, on the same side, and the same
    scale and shear; and the sweep's check of its samples (``_interp_errors``) the same
    errors as body by body."""
    from rls_addon.core.scan.sweep import _interp_error, _interp_errors

    rng = np.random.default_rng(9)
    times = np.linspace(0.0, 0.1, 9)
    mats = np.array([tr.at(times) for tr in tracks(rng, 40) if len(tr.times) > 1])
    mats[::5, 4:] = mats[::5, 4:] @ np.diag([-1.0, 1.0, 1.0, 1.0])  # a flip mid-sweep
    mats[1::5] = mats[1::5, :1]  # parked the whole sweep (is_static, made together)
    mats[2::5, -1, 0, 3] = np.nextafter(mats[2::5, 0, 0, 3], np.inf)  # all but one ulp
    mats[2::5, :-1] = mats[2::5, :1]
    for one, many in zip([Track(times, m) for m in mats] + [Track(times[:2], mats[0, :2])],
                         Track.many(times, mats) + Track.many(times[:2], mats[:1, :2])):
        assert np.array_equal(one._quat, many._quat) and np.array_equal(one._scale, many._scale)
        assert np.array_equal(one.velocities, many.velocities)
        assert one.is_static is many.is_static
        assert np.array_equal(one.at(times[:-1] + 0.003), many.at(times[:-1] + 0.003))
    probe_t = (times[1:] + times[:-1]) / 2
    probe = mats[:, :8] + rng.normal(0, 1e-4, (len(mats), 8, 4, 4))
    points = [rng.normal(size=(2, 3)) for _ in mats]
    assert _interp_errors(times, mats, probe_t, probe, points) == \
        [_interp_error(times, m, probe_t, p, q) for m, p, q in zip(mats, probe, points)]


def test_tracks_of_samples_decomposed_as_read_are_those_decomposed_together():
    """A sweep decomposes its samples as it reads them (``polar_parts`` of the first
    five, then of each round's midpoints, interleaved: ``sweep._interleaved``) and
    makes its tracks of them (``Track.many``'s ``parts``): the tracks decomposing all
    of them together gives, byte for byte (driving, accelerating, turning, tumbling,
    sheared and mirrored bodies, a flip mid-sweep; 5, 9 and 17 samples)."""
    from rls_addon.core.scan.sweep import _interleaved
    from rls_addon.core.scene.motion import polar_parts

    rng = np.random.default_rng(11)
    times = np.linspace(0.0, 0.1, 17)
    mats = np.array([tr.at(times) for tr in tracks(rng, 30) if len(tr.times) > 1])
    mats[::4, 9:] = mats[::4, 9:] @ np.diag([-1.0, 1.0, 1.0, 1.0])
    parts = polar_parts(mats[:, ::4])
    for step in (4, 2, 1):
        every = mats[:, ::step]
        if step < 4:
            parts = tuple(_interleaved(a, b) for a, b in zip(parts, polar_parts(mats[:, step::2 * step])))
        for made, together in zip(Track.many(times[::step], every, parts),
                                  Track.many(times[::step], every)):
            assert np.array_equal(made._quat, together._quat)
            assert np.array_equal(made._scale, together._scale)
            assert np.array_equal(made.at(times[:-1] + 0.002), together.at(times[:-1] + 0.002))


def test_a_frames_ray_origins_in_c_come_with_their_bounds(monkeypatch):
    """The C origins are read-only and their column bounds, found in the same pass, are
    kept: numpy's least and greatest of them (driving, accelerating, turning,
    mirrored tracks; times out of order and beyond the sweep). A NaN time keeps none
    (numpy's bounds are NaN there)."""
    from rls_addon.core.native import vectors
    from rls_addon.core.scene import track_set

    rng = np.random.default_rng(7)
    for track in tracks(rng, 12):
        if len(track.times) < 2 or track.is_static:
            continue  # answered by Track.positions_at
        monkeypatch.setattr(vectors, "_BOUNDS", [])
        t = rng.uniform(-0.02, 0.12, 70000)  # two shares on two threads
        got = track_set.positions_at(track, t)
        assert not got.flags.writeable and vectors._BOUNDS[0][0]() is got
        lo, hi = vectors._BOUNDS[0][1]
        assert np.array_equal(lo, got.min(axis=0)) and np.array_equal(hi, got.max(axis=0))
        t[17] = np.nan
        monkeypatch.setattr(vectors, "_BOUNDS", [])
        got = track_set.positions_at(track, t)
        assert vectors._BOUNDS == [] and np.isnan(vectors.column_bounds(got)[0]).all()


def test_a_firings_shared_time_gives_each_channel_the_bits_it_computes_alone():
    """tracks.c copies the row above when a ray's time is the same to the bit (the
    channels of a firing): every row has the bits it gets evaluated among rows of its
    own time only, with -0.0 and 0.0 (equal, not the same bits) side by side, where a
    copy by ``==`` or a copy of a row further up would give a zero of the wrong sign."""
    from rls_addon.core.scene import track_set

    assert track_set.TRACK_POSITIONS.get() is not None  # the library is built here
    m = np.array([np.eye(4)] * 3)
    m[:, :3, 3] = [[-0.0, -0.0, -0.0], [-1, -1, -1], [-3, -2, -1]]
    rng = np.random.default_rng(8)
    for track in [Track(np.array([0.0, 0.1, 0.2]), m)] + tracks(rng, 12)[:6]:
        if len(track.times) < 2 or track.is_static:
            continue
        t = np.repeat(np.concatenate([np.tile([0.0, -0.0, -0.0, 0.0], 80),
                                      np.linspace(-0.01, 0.11, 300)]), 2)
        got = track_set.positions_at(track, t)
        for v in np.unique(t.view(np.int64)).view(np.float64):
            alone = track_set.positions_at(track, np.full(256, v))[0]
            rows = got[t.view(np.int64) == np.float64(v).view(np.int64)]
            assert (rows.view(np.int64) == alone.view(np.int64)).all(), v


def test_origins_centred_in_the_same_pass_are_shifteds_difference(monkeypatch):
    """With a centre, tracks.c writes the origins centred on it too: what
    ``vectors.shifted`` then gives for them is numpy's ``origins - centre`` byte for
    byte (driving, accelerating, turning, mirrored tracks; a firing's channels at one
    time; far from the world's origin), read-only, with its bounds kept as they are
    kept for a difference worked out in numpy; another centre, or another array with
    the same numbers, is worked out anew."""
    from rls_addon.core.native import vectors
    from rls_addon.core.scene import track_set

    rng = np.random.default_rng(9)
    for track in tracks(rng, 12):
        if len(track.times) < 2 or track.is_static:
            continue
        monkeypatch.setattr(vectors, "_BOUNDS", [])
        monkeypatch.setattr(vectors, "_SHIFTED", [])
        m = track.matrices.copy()
        m[:, :3, 3] += [4e5, -3e3, 12.0]
        track = Track(track.times, m)
        t = np.repeat(rng.uniform(-0.02, 0.12, 35000), 2)  # two shares on two threads
        c = np.array([4e5 + 0.3, -3e3 - 1e-7, 11.0])
        got = track_set.positions_at(track, t, c)
        assert np.array_equal(got, track.positions_at(t))
        centred = vectors.shifted(got, c)
        want = np.asarray(got) - c
        assert centred.tobytes() == want.tobytes() and not centred.flags.writeable
        assert vectors._BOUNDS[0][0]() is centred
        lo, hi = vectors.column_bounds(centred)
        assert np.array_equal(lo, want.min(axis=0)) and np.array_equal(hi, want.max(axis=0))
        other = vectors.shifted(got, c + [1e-6, 0, 0])
        assert other is not centred and other.tobytes() == (got - (c + [1e-6, 0, 0])).tobytes()
        copy = got.copy()
        assert vectors.shifted(copy, c) is not centred
