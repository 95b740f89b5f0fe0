"""Which rays of a frame may straddle a depth discontinuity (``footprint`` samples the
beam's footprint only there): the neighbour pairs of a pattern, and the pairs across
an edge in one frame.

``candidates`` tests every neighbour pair (about two per ray) each frame, so it runs
in C (``native/c/edges.c``, in the library of the compiled Embree loop, on all cores)
where that library is built, else in numpy (``edges_numpy``): the readable reference
the C code follows operation by operation, so both mark the same pairs
(tests/core/test_footprint_native.py).
"""

import ctypes

import numpy as np

from ..native.kernels import Kernel, threads
from ..native.vectors import row_dot

NATIVE_EDGES_ABI = 2


def neighbour_pairs(pattern):
    """(a, b) index arrays of neighbouring rays in ``pattern``: consecutive rays of each
    channel (a spinning channel's next azimuth, a Risley or MEMS trace's next point);
    across channels, when every channel fires equally often, the ray of the channel
    next in elevation nearest in azimuth (a fixed shift in its firing count: channels
    fire at their own azimuth offsets), else consecutive rays in firing order. Kept on
    the pattern."""
    got = pattern.__dict__.get("_neighbour_pairs")
    if got is not None:
        return got
    ch = np.asarray(pattern.channels)
    n = len(ch)
    order = np.argsort(ch, kind="stable")
    same = ch[order[:-1]] == ch[order[1:]]
    a, b = [order[:-1][same]], [order[1:][same]]
    counts = np.bincount(ch) if n else np.zeros(0, np.int64)
    used = np.nonzero(counts)[0]
    if len(used) > 1 and np.all(counts[used] == counts[used[0]]):
        grid = order.reshape(len(used), -1)
        d = np.asarray(pattern.directions)
        grid = grid[np.argsort(d[grid, 2].mean(axis=1), kind="stable")]
        # each channel's k-th ray against the next channel's ray nearest in azimuth:
        # channels fire at their own azimuth offsets (a fixed shift in index)
        az = np.arctan2(d[grid, 1], d[grid, 0])
        step = np.median(_wrap(np.diff(az, axis=1)), axis=1) if grid.shape[1] > 1 \
            else np.zeros(len(grid))
        shift = np.median(_wrap(az[1:] - az[:-1]), axis=1)
        k = np.where(step[:-1] != 0, np.rint(shift / np.where(step[:-1] != 0, step[:-1], 1)), 0)
        for r in range(len(grid) - 1):
            a.append(grid[r])
            b.append(np.roll(grid[r + 1], int(k[r])))
    elif n > 1 and len(used) > 1:
        a.append(np.arange(n - 1))
        b.append(np.arange(1, n))
    got = (np.concatenate(a).astype(np.int64), np.concatenate(b).astype(np.int64))
    pattern.__dict__["_neighbour_pairs"] = got
    return got


def _wrap(angle):
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def candidates(pattern, hit, dist, normals, dirs, origins, step):
    """(a, b): the neighbour pairs across a depth discontinuity (see ``edges_numpy``),
    in C where it is built."""
    a, b = neighbour_pairs(pattern)
    fn = KERNEL.get() if compiled else None
    edge = edges_numpy(a, b, hit, dist, normals, dirs, origins, step) if fn is None \
        else _edges_native(fn, a, b, hit, dist, normals, dirs, origins, step)
    return a[edge], b[edge]


def edges_numpy(a, b, hit, dist, normals, dirs, origins, step):
    """The reference: per pair (a, b), whether it lies across a depth discontinuity: one
    ray hits and the other does not, or neither lies within ``step`` of the other's
    plane (the range each ray would have on the plane of the other's hit, along its own
    direction): a step in depth, not a surface seen at a slant (the ground's
    neighbouring channels differ by metres in range and lie on one plane). ``dist`` is
    read only where ``hit``."""
    ha, hb = hit[a], hit[b]
    edge = ha != hb
    # a step beyond ``step`` changes the range by about as much: only pairs whose ranges
    # differ by more are tested against each other's plane (a slanted surface's are)
    with np.errstate(invalid="ignore"):
        both = np.nonzero(ha & hb & (np.abs(dist[a] - dist[b]) > step))[0]
    if len(both):
        i, j = a[both], b[both]
        di, dj = dirs.take(i, axis=0), dirs.take(j, axis=0)
        ni, nj = normals.take(i, axis=0), normals.take(j, axis=0)
        ri, rj = dist[i], dist[j]

        with np.errstate(divide="ignore", invalid="ignore"):
            if origins.shape[0] == 1:
                # one origin: ray j on the plane of i's hit, ray i on the plane of j's
                tj = ri * row_dot(ni, di) / row_dot(ni, dj)
                ti = rj * row_dot(nj, dj) / row_dot(nj, di)
            else:
                oi, oj = origins.take(i, axis=0), origins.take(j, axis=0)
                tj = row_dot(ni, oi + di * ri[:, None] - oj) / row_dot(ni, dj)
                ti = row_dot(nj, oj + dj * rj[:, None] - oi) / row_dot(nj, di)
            edge[both] = ~(np.abs(tj - rj) <= step) & ~(np.abs(ti - ri) <= step)
    return edge


class _EdgesArgs(ctypes.Structure):
    """``edges_t`` of native/c/edges.c."""

    _fields_ = [("n", ctypes.c_int64), ("a", ctypes.c_void_p), ("b", ctypes.c_void_p),
                ("hit", ctypes.c_void_p), ("dist", ctypes.c_void_p),
                ("normal", ctypes.c_void_p), ("dir", ctypes.c_void_p),
                ("origin", ctypes.c_void_p), ("origin_per_ray", ctypes.c_int),
                ("step", ctypes.c_double), ("edge", ctypes.c_void_p)]


# Off: every frame tests its pairs in numpy (the reference the C code is tested against).
compiled = True
KERNEL = Kernel("rls_depth_edges", "rls_edges_abi", NATIVE_EDGES_ABI,
                [ctypes.POINTER(_EdgesArgs), ctypes.c_int])


def edges_args(a, b, hit, dist, normals, dirs, origins, step, edge=None):
    """(``edges_t`` of the pairs, the arrays it points into: keep them alive while it
    is used); ``edge``: the uint8 array it marks, or None."""
    def c(x, dtype):
        return np.ascontiguousarray(x, dtype=dtype)

    keep = [c(a, np.int64), c(b, np.int64), c(hit, np.uint8), c(dist, np.float64),
            c(normals, np.float64), c(dirs, np.float64), c(origins, np.float64)]
    args = _EdgesArgs(len(a), *(x.ctypes.data for x in keep), int(origins.shape[0] != 1),
                      float(step), 0 if edge is None else edge.ctypes.data)
    return args, keep


def _edges_native(fn, a, b, hit, dist, normals, dirs, origins, step):
    edge = np.empty(len(a), np.uint8)
    args, _keep = edges_args(a, b, hit, dist, normals, dirs, origins, step, edge)
    fn(ctypes.byref(args), threads())
    return edge.view(bool)
