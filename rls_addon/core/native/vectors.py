"""Row-wise vector arithmetic on (N, 3) arrays, in one fixed order of operations.

The numpy references and the compiled kernels (native/c/embree_loop.c, points.c,
edges.c, ghosts.c) sum a dot product left to right, ((x0 y0 + x1 y1) + x2 y2), so
both give the same bits. numpy's einsum sums in an order of its own build's choosing
((x0 y0 + x2 y2) + x1 y1 on the project's machine), so the references use this.
And the bounds of such an array's columns, fast (``column_bounds``)."""

import weakref

import numpy as np


def row_dot(a, b):
    """Dot products of the rows of ``a`` and ``b`` ((N, 3), or broadcasting to it),
    summed left to right."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


# the last read-only arrays whose bounds were asked for, and them: a driving sensor's
# origins per ray (and the same centred on its prepared scene) are bounded four times
# a frame (the prepared scene's cover, the re-check's octant table and its limit, the
# ground-truth boxes' cones). Four frames' worth: a frame's boxes are worked out
# behind the scan (output/io/behind.py), when the next two frames' origins may be
# made already (a driving sensor's steps overlap, scan/run.py). Held by weak
# reference: the cache keeps no array alive.
_BOUNDS = []
_KEEP = 8
_FOLD = 32  # rows folded side by side, so that numpy reduces along long rows


def _whole_view(a, kept):
    """True when ``a`` is a view of all of ``kept`` as it is (``reshape(-1, 3)`` of
    it): the same numbers, which cannot change."""
    return (isinstance(a, np.ndarray) and a.base is kept and a.shape == kept.shape
            and a.strides == kept.strides and a.dtype == kept.dtype
            and a.__array_interface__["data"][0] == kept.__array_interface__["data"][0])


def keep_bounds(a, lo, hi):
    """Remember (``lo``, ``hi``) as ``column_bounds(a)`` for a read-only (N, 3) array
    that owns its data (whose contents cannot change), found by whoever made it (a
    compiled kernel, in the pass that wrote it); ``a`` is returned."""
    if isinstance(a, np.ndarray) and a.base is None and not a.flags.writeable:
        others = [(ref, got) for ref, got in _BOUNDS if ref() is not None and ref() is not a]
        _BOUNDS[:] = [(weakref.ref(a), (np.array(lo, np.float64), np.array(hi, np.float64)))] \
            + others[:_KEEP - 1]
    return a


# (array, shift, a - shift) made by whoever made the array (a compiled kernel, in the
# pass that wrote it: a driving sensor's ray origins and the same centred on its
# prepared scene), for shifted to give
_SHIFTED = []


def keep_shifted(a, c, centred):
    """Remember ``centred`` (``a - c``, the same bits, found by whoever made ``a``) as
    ``shifted(a, c)``'s answer, for a read-only ``a`` that owns its data; ``centred``
    is made read-only."""
    if isinstance(a, np.ndarray) and a.base is None and not a.flags.writeable:
        centred.flags.writeable = False
        _SHIFTED[:] = [(a, np.array(c, np.float64).reshape(3), centred)]
    return a


def shifted(a, c):
    """``a - c`` for an (N, 3) float64 array and a (3,) shift, the same bits, read-only:
    the rows folded ``_FOLD`` at a time (numpy's broadcast over rows of three costs
    2.5x as much). When ``a``'s bounds are kept (``column_bounds``), the result's are
    kept too: rounding keeps order, so the least of the differences is the least
    minus ``c`` (a driving sensor's origins, centred on its prepared scene). When its
    maker worked ``a - c`` out already (``keep_shifted``), that array is the answer."""
    c = np.asarray(c, np.float64).reshape(3)
    for kept, shift, centred in _SHIFTED:
        if (kept is a or _whole_view(a, kept)) and shift.tobytes() == c.tobytes():
            got = _kept_bounds(a)
            if got is not None:
                keep_bounds(centred, got[0] - c, got[1] - c)
            return centred
    m = np.ascontiguousarray(a, np.float64).reshape(-1, 3)
    n = len(m) - len(m) % _FOLD
    out = np.empty_like(m)
    if n:
        np.subtract(m[:n].reshape(-1, 3 * _FOLD), np.tile(c, _FOLD),
                    out=out[:n].reshape(-1, 3 * _FOLD))
    np.subtract(m[n:], c, out=out[n:])
    out.flags.writeable = False
    got = _kept_bounds(a)
    if got is not None:
        keep_bounds(out, got[0] - c, got[1] - c)
    return out


def _kept_bounds(a):
    """The kept (lo, hi) of ``a`` (the array itself or a whole view of it), or None."""
    for ref, got in list(_BOUNDS):
        kept = ref()
        if kept is not None and (kept is a or _whole_view(a, kept)):
            return got
    return None


def column_bounds(a):
    """((3,) least, (3,) greatest) of the columns of an (N, 3) array with N >= 1.
    numpy reduces an (N, 3) array along its rows (or a strided column) slowly: the
    rows are folded ``_FOLD`` at a time into long ones first (the same extremes).
    The answers for the last two read-only arrays that own their data (whose
    contents cannot change) are kept for the next calls with them."""
    got = _kept_bounds(a)
    if got is not None:
        return got[0].copy(), got[1].copy()
    m = np.asarray(a, np.float64).reshape(-1, 3)
    n = len(m) - len(m) % _FOLD
    if n:
        wide = np.ascontiguousarray(m[:n]).reshape(-1, 3 * _FOLD)
        lo = wide.min(axis=0).reshape(_FOLD, 3).min(axis=0)
        hi = wide.max(axis=0).reshape(_FOLD, 3).max(axis=0)
        if n < len(m):
            lo, hi = np.minimum(lo, m[n:].min(axis=0)), np.maximum(hi, m[n:].max(axis=0))
    else:
        lo, hi = m.min(axis=0), m.max(axis=0)
    keep_bounds(a, lo, hi)  # (kept only for a read-only array that owns its data)
    return lo, hi


def triangle_bounds(vertices, triangles):
    """((T, 3) least, (T, 3) greatest) corner of each triangle's box: its three
    vertices compared pairwise, column by column (the same numbers as numpy's min and
    max over the corner axis of ``vertices[triangles]``, a NaN included, six times
    faster: numpy reduces along a short axis slowly)."""
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    a, b, c = vertices[t[:, 0]], vertices[t[:, 1]], vertices[t[:, 2]]
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
