"""Many tracks evaluated at once: a frame asks where each of its moving objects is at a
time of its own (a box's reference time, the sweep start, both sides of a velocity's
difference), and asking every ``Track`` on its own costs a few dozen small numpy
calls each time (``Track.at`` was called 3,700 times in 20 frames through traffic).

``TrackSet(tracks).at(which, t)`` gives, for every row r, ``tracks[which[r]].at(t[r])``
byte for byte: the same knots, the same interpolation (cubic Hermite translation,
quaternion slerp, linear scale and shear) and the same arithmetic, element by element
(tested in ``tests/core/test_track_set.py``), in one evaluation over all rows.
"""

import ctypes

import numpy as np

from ..native import kernels
from ..native.kernels import Kernel
from ..native.vectors import keep_bounds, keep_shifted
from .motion import Track, hermite, matrix_from_quat, slerp


def positions_at(track, t, centre=None):
    """(N, 3) ``track.positions_at(t)`` (its reference), in C where it is built
    (``native/c/tracks.c``: the same bits) for the many times of a frame's rays, each
    firing at its own time. From C the array is read-only and its column bounds,
    found in the same pass, are kept (``vectors.keep_bounds``): a frame asks for them
    four times (its prepared scene's cover, the re-check's octant table and limit).
    With ``centre`` ((3,): the prepared scene's, which its cast centres the origins on)
    C also writes them centred, in the same pass, and ``vectors.shifted(positions,
    centre)`` gives that array (``vectors.keep_shifted``)."""
    t = np.asarray(t, np.float64).reshape(-1)
    fn = TRACK_POSITIONS.get() if compiled and len(t) >= 256 else None
    if fn is None or len(track.times) < 2 or track.is_static:
        return track.positions_at(t)
    knots = [np.ascontiguousarray(track.times), np.ascontiguousarray(track.matrices[:, :3, 3]),
             np.ascontiguousarray(track.velocities, np.float64), np.ascontiguousarray(t)]
    out = np.empty((len(t), 3))
    bounds = np.empty(6)
    c = None if centre is None else np.array(centre, np.float64).reshape(3)
    centred = None if c is None else np.empty((len(t), 3))
    args = _PositionsArgs(len(knots[0]), *(a.ctypes.data for a in knots[:3]), len(t),
                          knots[3].ctypes.data, out.ctypes.data, bounds.ctypes.data, 0,
                          None if c is None else c.ctypes.data,
                          None if c is None else centred.ctypes.data)
    fn(ctypes.byref(args), kernels.threads())
    out.flags.writeable = False
    if not args.nan:
        keep_bounds(out, bounds[:3], bounds[3:])
    if c is not None:
        keep_shifted(out, c, centred)
    return out


class _PositionsArgs(ctypes.Structure):
    """``positions_t`` of native/c/tracks.c."""

    _fields_ = [("knots", ctypes.c_int64), ("times", ctypes.c_void_p),
                ("position", ctypes.c_void_p), ("velocity", ctypes.c_void_p),
                ("n", ctypes.c_int64), ("t", ctypes.c_void_p), ("out", ctypes.c_void_p),
                ("bounds", ctypes.c_void_p), ("nan", ctypes.c_int32),
                ("centre", ctypes.c_void_p), ("centred", ctypes.c_void_p)]


NATIVE_TRACKS_ABI = 3
TRACK_POSITIONS = Kernel("rls_track_positions", "rls_tracks_abi", NATIVE_TRACKS_ABI,
                         [ctypes.POINTER(_PositionsArgs), ctypes.c_int])
# Off: a frame's ray origins come from Track.positions_at (the reference the C code is
# tested against).
compiled = True


_IDENTITY_QUAT = np.array([[1.0, 0.0, 0.0, 0.0]])
_IDENTITY_3 = np.eye(3)[None]


class TrackSet:
    """``tracks`` ([Track]) side by side: their knots concatenated, each track's first
    knot at ``first[k]``."""

    def __init__(self, tracks):
        self.tracks = list(tracks)
        counts = np.array([len(tr.times) for tr in self.tracks], np.int64)
        self.first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        self.counts = counts
        # a track that answers its first matrix at every time (Track.at's own test)
        self.still = np.array([len(tr.times) == 1 or tr.is_static for tr in self.tracks], bool)
        if not self.tracks:
            return
        self.times = np.concatenate([tr.times for tr in self.tracks])
        self.positions = np.concatenate([tr.matrices[:, :3, 3] for tr in self.tracks])
        self.velocities = np.concatenate([tr.velocities for tr in self.tracks])
        # a still track's rows are its first matrix (``starts``): its quaternions and
        # scales are never read, so it is not decomposed for them (``Track._quat``)
        self.quats = np.concatenate([_IDENTITY_QUAT.repeat(len(tr.times), 0) if still
                                     else tr._quat for tr, still in zip(self.tracks, self.still)])
        self.scales = np.concatenate([_IDENTITY_3.repeat(len(tr.times), 0) if still
                                      else tr._scale for tr, still in zip(self.tracks, self.still)])
        self.starts = np.array([tr.matrices[0] for tr in self.tracks])
        # (K, longest) knot times, padded with +inf: a row's segment is counted in one
        # comparison (searchsorted on each track's own times, side="right")
        padded = np.full((len(self.tracks), int(counts.max())), np.inf)
        for k, tr in enumerate(self.tracks):
            padded[k, :len(tr.times)] = tr.times
        self._padded = padded

    @classmethod
    def of(cls, tracks_or_none, matrices):
        """A set of one track per object: ``tracks_or_none[k]``, or a fixed track at
        ``matrices[k]`` where it is None (an object that did not move)."""
        return cls([tr if tr is not None else Track.fixed(m)
                    for tr, m in zip(tracks_or_none, matrices)])

    def _segments(self, which, t):
        """Per row: the global index of its segment's first knot, the fraction ``a``
        and the segment's length (``Track._segments`` of its own track)."""
        k = self.counts[which]
        right = np.count_nonzero(self._padded[which] <= t[:, None], axis=1)
        i = np.clip(right - 1, 0, np.maximum(k - 2, 0)) + self.first[which]
        moving = ~self.still[which]
        i = np.where(moving, i, self.first[which])  # a still row's knots are never read
        nxt = np.where(moving, i + 1, i)
        span = self.times[nxt] - self.times[i]
        a = np.clip((t - self.times[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
        return i, nxt, a, span, moving

    def at(self, which, t):
        """(N, 4, 4): row r is ``self.tracks[which[r]].at([t[r]])[0]``."""
        which = np.asarray(which, np.int64).reshape(-1)
        t = np.asarray(t, np.float64).reshape(-1)
        out = np.empty((len(t), 4, 4))
        out[:] = np.eye(4)
        if not len(t):
            return out
        i, nxt, a, span, moving = self._segments(which, t)
        p, v = self.positions, self.velocities
        out[:, :3, 3] = hermite(p[i], v[i], p[nxt], v[nxt], a, span)
        rot = matrix_from_quat(slerp(self.quats[i], self.quats[nxt], a))
        scale = self.scales[i] * (1 - a)[:, None, None] + self.scales[nxt] * a[:, None, None]
        out[:, :3, :3] = rot @ scale
        still = np.nonzero(~moving)[0]
        if len(still):
            out[still] = self.starts[which[still]]
        return out

    def positions_at(self, which, t):
        """(N, 3): row r is ``self.tracks[which[r]].positions_at([t[r]])[0]``."""
        which = np.asarray(which, np.int64).reshape(-1)
        t = np.asarray(t, np.float64).reshape(-1)
        if not len(t):
            return np.zeros((0, 3))
        i, nxt, a, span, moving = self._segments(which, t)
        p, v = self.positions, self.velocities
        out = hermite(p[i], v[i], p[nxt], v[nxt], a, span)
        still = np.nonzero(~moving)[0]
        if len(still):
            out[still] = self.starts[which[still], :3, 3]
        return out
