"""What every ground-truth box of a frame counts, all boxes in one pass over the rays
toward them (``ray_cells.RayCells.segments``): the rays that cross a box within range
and whether each reached the box's object or something in front of it (its
visibility), and the real points on those rays inside the box grown by a margin; and
the ray that faces an object that returned nothing.

In C (``native/c/boxes.c``) where it is built, else ``box_counts_numpy`` over (box,
ray) and (box, point) pairs. Each test is the per-box reference's
(``box_reference``), element by element: a ray's or a point's offset from a box's
centre turned into the box's axes row by row (``_in_axes``: the sums in the order of
numpy's product of an (N, 3) array and a 3x3 matrix), the same slab test and the same
comparisons, so the counts are the reference's whatever superset of candidates each
side looked at (tested against it).
"""

import ctypes
import math

import numpy as np

from ..native import kernels
from ..native.kernels import Kernel


def box_counts(cells, objects, poses, sizes, margin, rmax, ranges, real, segments):
    """Per box: (visible share, rays on it, real points inside it grown by
    ``margin``), over the rays of ``segments`` (``RayCells.segments``: a superset of
    the rays within each box's sphere, the larger of its silhouette's and its grown
    box's) and their points.

    objects  per box, its object's index into ``rays.objects`` (-2: none)
    poses    (B, 4, 4) box frames; sizes (B, 3)
    ranges   per point, its range; real: per point, not a ghost"""
    fn = BOX_COUNTS.get() if compiled else None
    if fn is None:
        return box_counts_numpy(cells, objects, poses, sizes, margin, rmax, ranges, real,
                                segments)
    rays, n = cells.rays, len(poses)
    one = rays.origins.shape[0] == 1
    keep = [np.ascontiguousarray(poses[:, :3, 3]), np.ascontiguousarray(poses[:, :3, :3]),
            np.ascontiguousarray(sizes / 2), np.ascontiguousarray(sizes / 2 + margin),
            np.ascontiguousarray(objects, np.int32), _reaches(sizes, margin),
            *(np.ascontiguousarray(a, np.int64) for a in segments),
            np.ascontiguousarray(cells.cells.order, np.int64),
            np.ascontiguousarray(rays.origins, np.float64),
            np.ascontiguousarray(rays.dirs, np.float64),
            np.ascontiguousarray(rays.object, np.int32),
            np.ascontiguousarray(rays.dist, np.float64),
            np.ascontiguousarray(cells.pstart, np.int64),
            np.ascontiguousarray(cells.point_order, np.int64),
            np.ascontiguousarray(ranges, np.float64),
            np.ascontiguousarray(real, np.uint8)]
    seen, blocked, inside = (np.empty(n, np.int64) for _ in range(3))
    (centre, rot, half, grown, obj, reach, seg_box, seg_lo, seg_hi, order, origins, dirs, hit,
     dist, pstart, porder, rng, rl) = (a.ctypes.data for a in keep)
    args = _BoxesArgs(n, centre, rot, half, grown, obj, reach, len(keep[6]), seg_box, seg_lo,
                      seg_hi, order, origins, int(one), dirs, hit, dist, float(rmax), pstart,
                      porder, rng, rl, seen.ctypes.data, blocked.ctypes.data,
                      inside.ctypes.data)
    fn(ctypes.byref(args), kernels.threads())
    return _share(seen, blocked) + (inside,)


def box_counts_numpy(cells, objects, poses, sizes, margin, rmax, ranges, real, segments):
    """The reference of ``box_counts``: every (box, ray) pair of ``segments`` and every
    (box, point) pair of their points, tested at once."""
    box, ray = cells.pairs(segments)
    box, ray = _culled(cells.rays, poses[:, :3, 3], _reaches(sizes, margin), box, ray)
    share, on_box = visibility(cells.rays, objects, poses, sizes, rmax, box, ray)
    inside = points_inside(cells.rays, ranges, real, poses, sizes, margin,
                           *cells.points_of(box, ray))
    return share, on_box, inside


def _culled(rays, centres, reaches, box, ray):
    """The (box, ray) pairs whose ray passes within its box's reach ahead of its
    origin (as the compiled loop culls them: no ray left out can cross the box or
    hold a point inside it)."""
    rel = centres[box] - _origins(rays, ray)
    d = rays.dirs[ray]
    along = rel[:, 0] * d[:, 0] + rel[:, 1] * d[:, 1] + rel[:, 2] * d[:, 2]
    r = reaches[box]
    perp2 = rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1] + rel[:, 2] * rel[:, 2] - along * along
    keep = np.nonzero((along + r >= 0) & (perp2 <= r * r))[0]
    return box[keep], ray[keep]


def _reaches(sizes, margin):
    """Per box: a radius around its centre holding the box and the box grown by
    ``margin`` (what the compiled loop culls rays with before their slab test), padded
    by 0.1 mm: any ray within the box or with a point in the grown box passes within
    it, whatever the rounding of the cull's own sums (micrometres at a kilometre)."""
    half = sizes / 2
    return np.ascontiguousarray(np.linalg.norm(half + margin, axis=1) + 1e-4)


def _share(n_seen, n_blocked):
    """(share of the rays on each box that reached its object, NaN where none is on
    it; the rays on it)."""
    total = n_seen + n_blocked
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(total > 0, n_seen / np.maximum(total, 1), math.nan)
    return share, total


def _in_axes(v, rot, box):
    """(P, 3) offsets ``v`` turned into the axes of their boxes: ``v[p] @ rot[box[p]]``
    with the sums written out (what ``@`` computes for a row)."""
    r = rot[box]
    return v[:, 0, None] * r[:, 0, :] + v[:, 1, None] * r[:, 1, :] + v[:, 2, None] * r[:, 2, :]


def _origins(rays, ray):
    """The origins of rays ``ray``: the one origin (1, 3) or theirs."""
    return rays.origins if rays.origins.shape[0] == 1 else rays.origins[ray]


def visibility(rays, objects, poses, sizes, rmax, box, ray):
    """Per box: (share of the rays crossing it that reach its object, rays on it)
    (``box_reference._visibility``), from (box, ray) pairs that hold every ray
    crossing each box. ``objects``: per box, its object's index into
    ``rays.objects`` (-2: none)."""
    n = len(poses)
    centre, rot = poses[:, :3, 3], poses[:, :3, :3]
    o = _in_axes(_origins(rays, ray) - centre[box], rot, box)
    d = _in_axes(rays.dirs[ray], rot, box)
    half = (sizes / 2)[box]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (-half - o) * inv
        t2 = (half - o) * inv
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    t_in = np.minimum(t1, t2).max(axis=1)
    t_out = np.maximum(t1, t2).min(axis=1)
    on = (t_in <= t_out) & (t_out > 0) & (t_in <= rmax)
    hit, dist = rays.object[ray], rays.dist[ray]
    seen = on & (hit == np.asarray(objects)[box])
    blocked = on & ~seen & (hit >= 0) & (dist < np.maximum(t_in, 0) + 1e-6)
    return _share(np.bincount(box[seen], minlength=n), np.bincount(box[blocked], minlength=n))


def points_inside(rays, ranges, real, poses, sizes, margin, box, point):
    """Per box: how many real (not ghost) points lie inside it grown by ``margin``
    (``box_reference._inside``), from (box, point) pairs that hold every point near
    each box. A point's world position is its ray's (``RayRecord.point_world``)."""
    keep = real[point]
    box, point = box[keep], point[keep]
    pr = rays.point_ray[point]
    world = _origins(rays, pr) + rays.dirs[pr] * np.asarray(ranges, np.float64)[point][:, None]
    local = _in_axes(world - poses[box, :3, 3], poses[:, :3, :3], box)
    inside = np.all(np.abs(local) <= (sizes / 2 + margin)[box], axis=1)
    return np.bincount(box[inside], minlength=len(poses))


def facing_ray(cells, centre):
    """Index of the ray pointing most nearly at ``centre`` from its own origin (the
    first of equals, as over all rays), looking only at cones of rays around it,
    widening until the best in a cone lies within the cone's own angle of the centre
    (then no ray outside can be better); None when no cone settles it."""
    rays = cells.rays
    v = np.asarray(centre, np.float64) - cells.o0
    dist = float(np.linalg.norm(v))
    if dist <= cells.travel + 1e-9:
        return None
    drift = math.asin(min(1.0, cells.travel / dist))
    angle = 0.02
    while angle + drift < math.pi / 4:
        idx = cells.within(v, angle + drift)
        if len(idx):
            k, cos = facing(rays, centre, idx)
            if cos >= math.cos(angle):
                return k
        angle *= 4.0
    return None


def facing_rays(cells, centres):
    """``facing_ray`` of many centres ((N, 3)) at once: per centre, the index of the
    ray pointing most nearly at it (the first of equals), or -1 where no cone settles
    it. Each round of widening looks at every unsettled centre's cone together (the
    same cones, the same cosines, row by row, as ``facing``)."""
    rays = cells.rays
    centres = np.asarray(centres, np.float64).reshape(-1, 3)
    best = np.full(len(centres), -1, np.int64)
    v = centres - cells.o0
    dist = np.array([float(np.linalg.norm(x)) for x in v])
    open_ = [q for q in range(len(centres)) if dist[q] > cells.travel + 1e-9]
    drift = {q: math.asin(min(1.0, cells.travel / dist[q])) for q in open_}
    angle = 0.02
    while open_:
        open_ = [q for q in open_ if angle + drift[q] < math.pi / 4]
        if not open_:
            break
        owner, ray = cells.within_many(v[open_], [angle + drift[q] for q in open_])
        to = centres[open_][owner] - (rays.origins if rays.origins.shape[0] == 1
                                      else rays.origins[ray])
        to /= np.maximum(np.linalg.norm(to, axis=1, keepdims=True), 1e-12)
        dots = np.einsum("ij,ij->i", to, rays.dirs[ray])
        k, top = _first_best(owner, ray, dots, len(open_))
        settled = top >= math.cos(angle)
        for i in np.nonzero(settled)[0]:
            best[open_[i]] = k[i]
        open_ = [q for q, s in zip(open_, settled) if not s]
        angle *= 4.0
    return best


def _first_best(owner, ray, dots, n):
    """Per owner 0..n-1: (the least ray of those with its greatest dot, that dot);
    (-1, -inf) for an owner with none."""
    top = np.full(n, -np.inf)
    np.maximum.at(top, owner, dots)
    k = np.full(n, np.iinfo(np.int64).max)
    mine = dots == top[owner]
    np.minimum.at(k, owner[mine], ray[mine])
    return np.where(np.isfinite(top), k, -1), top


def facing(rays, centre, idx):
    """Index (into all rays) of the ray among ``idx`` (sorted indices, or a slice)
    that points most nearly at ``centre`` from its own origin, and the cosine of its
    angle."""
    dirs = rays.dirs[idx]
    to = centre - (rays.origins if rays.origins.shape[0] == 1 else rays.origins[idx])
    to /= np.maximum(np.linalg.norm(to, axis=1, keepdims=True), 1e-12)
    dots = np.einsum("ij,ij->i", np.broadcast_to(to, dirs.shape), dirs)
    k = int(np.argmax(dots))
    return (k if isinstance(idx, slice) else int(idx[k])), float(dots[k])


class _BoxesArgs(ctypes.Structure):
    """``boxes_t`` of native/c/boxes.c."""

    _fields_ = [("boxes", ctypes.c_int64), ("centre", ctypes.c_void_p),
                ("rot", ctypes.c_void_p), ("half", ctypes.c_void_p),
                ("grown", ctypes.c_void_p), ("object", ctypes.c_void_p),
                ("reach", ctypes.c_void_p),
                ("segments", ctypes.c_int64), ("seg_box", ctypes.c_void_p),
                ("seg_lo", ctypes.c_void_p), ("seg_hi", ctypes.c_void_p),
                ("order", ctypes.c_void_p), ("origins", ctypes.c_void_p),
                ("one_origin", ctypes.c_int64), ("dirs", ctypes.c_void_p),
                ("hit", ctypes.c_void_p), ("dist", ctypes.c_void_p), ("rmax", ctypes.c_double),
                ("pstart", ctypes.c_void_p), ("point_order", ctypes.c_void_p),
                ("range", ctypes.c_void_p), ("real", ctypes.c_void_p),
                ("seen", ctypes.c_void_p), ("blocked", ctypes.c_void_p),
                ("inside", ctypes.c_void_p)]


class _OwnPointsArgs(ctypes.Structure):
    """``own_points_t`` of native/c/boxes.c."""

    _fields_ = [("n", ctypes.c_int64), ("base", ctypes.c_void_p), ("stride", ctypes.c_int64),
                ("off_instance", ctypes.c_int64), ("off_ghost", ctypes.c_int64),
                ("off_time", ctypes.c_int64), ("keys", ctypes.c_int64),
                ("key", ctypes.c_void_p), ("group", ctypes.c_void_p),
                ("next", ctypes.c_void_p), ("first", ctypes.c_void_p),
                ("times", ctypes.c_void_p)]


def own_groups(pts, keys):
    """The real (not ghost) points whose instance id is one of ``keys`` (sorted, unique
    uint32), grouped by key in one compiled pass over the point records: (``first``,
    keys + 1 group starts; the groups' times, each group in the points' order), what
    ``ground_truth._own_groups_numpy`` gives; None where the library is not built or
    the records are not the scan's (uint32 ids, uint8 ghost flags, float64 times)."""
    fn = OWN_POINTS.get() if compiled else None
    fields = pts.dtype.fields if isinstance(pts, np.ndarray) else None
    want = {"instance": np.uint32, "ghost": np.uint8, "time": np.float64}
    if (fn is None or fields is None or pts.ndim != 1
            or any(name not in fields or fields[name][0] != np.dtype(t).newbyteorder("=")
                   for name, t in want.items())):
        return None
    keys = np.ascontiguousarray(keys, np.uint32)
    n = len(pts)
    group, nxt = np.empty(n, np.int32), np.empty(max(len(keys), 1), np.int64)
    first, times = np.empty(len(keys) + 1, np.int64), np.empty(n, np.float64)
    stride = pts.strides[0] if n else pts.dtype.itemsize
    args = _OwnPointsArgs(n, pts.ctypes.data, stride, fields["instance"][1],
                          fields["ghost"][1], fields["time"][1], len(keys), keys.ctypes.data,
                          group.ctypes.data, nxt.ctypes.data, first.ctypes.data,
                          times.ctypes.data)
    fn(ctypes.byref(args))
    return first, times[:first[-1]]


NATIVE_BOXES_ABI = 1
BOX_COUNTS = Kernel("rls_box_counts", "rls_boxes_abi", NATIVE_BOXES_ABI,
                    [ctypes.POINTER(_BoxesArgs), ctypes.c_int])
OWN_POINTS = Kernel("rls_own_points", "rls_own_points_abi", 1,
                    [ctypes.POINTER(_OwnPointsArgs)])
# Off: every frame counts its boxes (and groups their points) in numpy (the reference the C code is tested against).
compiled = True
