"""Watertight casting over any backend: rays aimed exactly at a shared edge or vertex
never slip between the triangles (see ``WatertightCaster``)."""

import numpy as np

from ..native.vectors import column_bounds, row_dot, triangle_bounds
from .base import CasterBase, cast_exact, refine_hits
from .envelope import ElevationEnvelope


# Generic (irrational-ish) vectors used to pick a perpendicular nudge for each retry.
_NUDGE_AXES = np.array([[0.7548776662, 0.5698402910, 0.3247179572],
                        [-0.2306, 0.8715, -0.4330],
                        [0.5773, -0.2113, 0.7887]])
_NUDGE_SCALES = (64.0,)  # in units of 1e-6 x (scene extent); the compiled loop nudges once
# (8, 3): per octant code, whether it moves negative along each axis (bit k)
_OCTANT_NEG = np.array([[(code >> k) & 1 for k in range(3)] for code in range(8)], bool)


def box_triangles(lo, hi):
    """Vertices (8K, 3) and triangles (12K, 3) of K axis-aligned boxes."""
    k = lo.shape[0]
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                        [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=bool)
    v = np.where(corners[None], hi[:, None, :], lo[:, None, :]).reshape(-1, 3)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    t = (faces[None] + 8 * np.arange(k)[:, None, None]).reshape(-1, 3)
    return v, t


def cluster_boxes(vertices, triangles, groups, cell):
    """Bounding boxes of triangles grouped by (group, spatial cell of the centroid)."""
    tmin, tmax = triangle_bounds(vertices, triangles)
    cells = np.floor((tmin + tmax) / (2 * cell)).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    key = np.asarray(groups, np.int64) * int(np.prod(span))
    key += (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    order = np.argsort(key, kind="stable")
    sk = key[order]
    starts = np.r_[0, np.nonzero(sk[1:] != sk[:-1])[0] + 1]
    return (np.minimum.reduceat(tmin[order], starts, axis=0),
            np.maximum.reduceat(tmax[order], starts, axis=0))


def _cross(a, b):
    """Row-wise cross products (embree_loop.c: cross3)."""
    a, b = np.broadcast_arrays(a, b)
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _unit(v):
    """Rows scaled to unit length (embree_loop.c: unit3)."""
    return v / np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])[:, None]


def outside_distance(vertices, triangles, tri, origins, directions):
    """How far (metres) each ray's crossing of its triangle's plane lies outside that
    triangle (0 inside; inf for rays parallel to the plane or crossing it behind the
    origin). float64, operation by operation as the compiled loop computes it."""
    t = triangles[tri]
    a, b, c = vertices[t[:, 0]], vertices[t[:, 1]], vertices[t[:, 2]]
    origins = np.broadcast_to(origins, directions.shape)
    n = _unit(_cross(b - a, c - a))
    denom = row_dot(n, directions)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = row_dot(n, a - origins) / denom
        x = origins + directions * s[:, None]
        out = np.zeros(len(tri))
        for p, q in ((a, b), (b, c), (c, a)):
            m = _unit(_cross(n, q - p))
            out = np.maximum(out, -row_dot(x - p, m))
    return np.where(np.isfinite(out) & (s > 0), out, np.inf)


def _clip_slab(lo, hi, d, near, far):
    """Narrow each ray's span [near, far] (updated in place) to where it lies between
    ``lo`` and ``hi`` (offsets from its origin) along one axis, ``d`` its direction's
    component there; a ray parallel to the slab keeps its span inside, loses it
    outside (embree_loop.c: may_reach_hull)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1, t2 = lo * inv, hi * inv
    flat = np.nonzero(d == 0)[0]
    if len(flat):
        inside = (lo[flat] <= 0) & (hi[flat] >= 0)
        t1[flat] = np.where(inside, -np.inf, np.inf)
        t2[flat] = np.where(inside, np.inf, -np.inf)
    np.maximum(near, np.minimum(t1, t2), out=near)
    np.minimum(far, np.maximum(t1, t2), out=far)


def _take(origins, rows):
    """The origins of rays ``rows``: the one shared origin, or theirs."""
    return origins if origins.shape[0] == 1 else origins[rows]


def _scatter(n, rows, got):
    """A cast of rays ``rows`` (dist, tri[, normals]) as a cast of all ``n`` rays, the
    others missing."""
    out = [np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))][:len(got)]
    for full, part in zip(out, got):
        full[rows] = part
    return tuple(out)


class WatertightCaster(CasterBase):
    """Makes any backend's float32 traversal watertight for rays that miss.

    Backends in float32 (BVHTree) let a ray aimed exactly at a shared edge or vertex
    slip between the neighbouring triangles. Misses are re-checked against a small
    'hull' of padded bounding boxes (of triangle clusters): a miss that enters no box
    is a real miss (sky rays cost one cheap extra cast); the others are re-cast once
    with the origin nudged perpendicular to the ray by 64e-6 of the scene's extent
    (a few hundred float32 ulps), and a nudged hit is kept only when the original ray
    crosses that triangle within float32 noise, so silhouettes do not grow. The caller
    refines the range against the hit triangle's plane along the *original* ray, so
    the nudge does not show in the range.
    """

    def __init__(self, factory, vertices, triangles, groups=None, cell=None):
        # A backend may offer a faster build for use behind this wrapper (Embree without
        # its robust mode): edge-exactness is this class's job then.
        self.primary = factory.behind_watertight(vertices, triangles)
        self.name = self.primary.name
        v = np.asarray(vertices, np.float64)
        # the bounds of every corner of every triangle (column_bounds: numpy's least
        # and greatest, reduced along long rows)
        lo_all, hi_all = column_bounds(v[np.asarray(triangles, np.int64).reshape(-1)])
        self.extent = float(np.linalg.norm(hi_all - lo_all)) + 1.0
        groups = np.zeros(len(triangles), np.int64) if groups is None else groups
        cell = max(self.extent / 32.0, 1.0) if cell is None else float(cell)
        lo, hi = cluster_boxes(v, np.asarray(triangles, np.int64), groups, cell)
        pad = 1e-5 * self.extent
        self.box_lo, self.box_hi = lo - pad, hi + pad
        hv, ht = box_triangles(self.box_lo, self.box_hi)
        self.hull = factory(hv, ht)
        self.v = np.ascontiguousarray(v)
        self.t = np.ascontiguousarray(triangles, dtype=np.int64)
        self.tol = 1e-6 * self.extent
        self.retried = 0
        self._octants = (None, None)  # the last octant table and its origins' bounds

    def cast(self, origins, directions, max_dist):
        d = np.asarray(directions, np.float64)
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        rows = self.rows_worth_casting(o, d, max_dist)
        if rows is None:
            dist, tri = self.primary.cast(o, d, max_dist)
        else:
            dist, tri = _scatter(len(d), rows, self.primary.cast(_take(o, rows), d[rows],
                                                                 max_dist))
        self._recheck(o, d, max_dist, dist, tri, reach=rows)
        return dist, tri

    def start_refined(self, origins, directions, max_dist, planes, order=None):
        """``cast`` with every hit refined (see ``cast_exact``): the primary cast is
        refined by its backend, the few rays won back by the re-check here. Casts
        right away (the re-check needs the primary cast's misses)."""
        d = np.asarray(directions, np.float64)
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        pending = self._start_compiled(o, d, max_dist, planes, order)
        if pending is not None:
            return pending
        rows = self.rows_worth_casting(o, d, max_dist)
        if rows is None:
            dist, tri, normals = cast_exact(self.primary, o, d, max_dist, planes, order)
        else:
            dist, tri, normals = _scatter(len(d), rows, cast_exact(
                self.primary, _take(o, rows), d[rows], max_dist, planes))
        self.win_back(o, d, max_dist, planes, dist, tri, normals, reach=rows)
        return lambda: (dist, tri, normals)

    def rows_worth_casting(self, o, d, max_dist):
        """The rays the primary build is asked to cast: all (None) for a backend whose
        rays cost little (Embree traces a sky ray in nanoseconds); for one that pays
        per ray (``skip_sure_misses``: a Python call each with BVHTree), the indices of
        the rays that may reach a hull box. Every triangle lies in a padded hull box,
        so the others surely miss: from a sensor above the ground, the rays to the sky
        and those passing beyond the ground's edge. From one origin, the boxes'
        ``ElevationEnvelope`` tells them apart (nearly as well as casting into the
        hull); from per-ray origins, the octant test (``may_reach_hull``)."""
        if not self.primary.skip_sure_misses or len(d) == 0:
            return None
        if o.shape[0] == 1:
            reach = ElevationEnvelope(o[0], self.box_lo, self.box_hi).may_meet(d)
        else:
            reach = self.may_reach_hull(o, d, max_dist, self.octant_boxes(o))
        return np.nonzero(reach)[0]

    # Off: every cast re-checks in numpy (the reference the compiled loop is tested
    # against).
    compiled = True

    def _start_compiled(self, o, d, max_dist, planes, order):
        """The cast with its re-check in the compiled loop's threads (Embree), or None
        where the loop or the hull cannot take it."""
        got = self.native_recheck(o, max_dist)
        if got is None:
            return None
        rc, keep = got
        pending = self.primary.start_rechecked(o, d, max_dist, planes, order, rc, keep=keep)
        if pending is None:
            return None

        def result():
            got = pending()
            self.retried += rc.retried
            return got

        return result

    def native_recheck(self, o, max_dist, planes=None, limit=False):
        """(``embree_loop.Recheck``, what must outlive it) for a cast from origins ``o``
        with the re-check in the compiled loop's threads, or None where the loop or the
        hull cannot take it (or ``compiled`` is off). With ``planes`` (the primary
        build's ``triangle_planes``), for an instanced cast whose static scene is
        instance 0 (``instancing.InstancedWorld``): its rays that do not hit it are
        re-checked after refinement, and with ``limit`` only up to their moving hit.
        The caller adds ``retried`` to ``self.retried`` once the cast is done."""
        primary_scene = getattr(self.primary, "native_scene", lambda: None)()
        hull_scene = getattr(self.hull, "native_scene", lambda: None)()
        if not self.compiled or primary_scene is None or hull_scene is None:
            return None
        from .embree_loop import Recheck

        boxes, has = (np.ascontiguousarray(a) for a in self.octant_boxes(o))
        pl = None if planes is None else np.ascontiguousarray(planes, np.float64)
        rc = Recheck(hull=hull_scene, boxes=boxes.ctypes.data, has=has.ctypes.data,
                     max_dist=float(max_dist),
                     vertices=self.v.ctypes.data, triangles=self.t.ctypes.data,
                     tol=self.tol, nudge=_NUDGE_SCALES[0] * 1e-6 * self.extent,
                     axis=tuple(_NUDGE_AXES[0]), scene=primary_scene,
                     planes=None if pl is None else pl.ctypes.data,
                     static_inst=-1 if pl is None else 0,
                     use_limit=int(bool(limit) and not self._starts_inside(o)), retried=0)
        return rc, (self, boxes, has, pl)

    def describe(self):
        return self.primary.describe()

    def win_back(self, o, d, max_dist, planes, dist, tri, normals, limit=None, reach=None):
        """Re-check the misses (``tri`` -1) of a refined cast of the primary build and
        write what they find, refined, into ``dist``, ``tri`` and ``normals``;
        returns the indices of the rays won back. ``limit`` (per ray): only a crack
        nearer than this matters (a ray that hit something else there). ``reach``:
        the indices of the rays that may reach the hull, when known."""
        got = self._recheck(o, d, max_dist, dist, tri, limit, reach)
        if len(got):
            dist[got], normals[got] = refine_hits(None, None, _take(o, got),
                                                  d[got], dist[got], tri[got], planes)
        return got

    def _recheck(self, o, d, max_dist, dist, tri, limit=None, reach=None):
        """Re-cast the misses that may have slipped through a crack (see the class
        docstring), writing what they find into ``dist`` and ``tri``; returns the
        indices of the rays won back. With ``limit`` (per ray), a miss whose path
        meets no hull box before its limit is not re-cast. ``reach``: the indices of
        the rays that may reach the hull (``may_reach_hull``) when already known."""
        won = []
        miss = self._misses_near_hull(o, d, max_dist, tri, reach)
        if len(miss) == 0:
            return np.zeros(0, np.int64)
        dm = d[miss]
        entry, inside = self.hull.cast(_take(o, miss), dm, max_dist)
        keep = inside >= 0
        if limit is not None and not self._starts_inside(o):
            keep &= entry <= limit[miss]
        miss = miss[keep]
        om = np.broadcast_to(o, d.shape)[miss] if o.shape[0] == 1 else o[miss]
        for axis, scale in zip(_NUDGE_AXES, _NUDGE_SCALES):
            if len(miss) == 0:
                break
            self.retried += len(miss)
            dm = d[miss]
            perp = _unit(_cross(dm, axis[None]))
            d2, t2 = self.primary.cast(om + perp * (scale * 1e-6 * self.extent), dm,
                                       max_dist)
            # Keep a nudged hit only if the *original* ray passes the hit triangle within
            # float32 noise: through a crack it does, past a silhouette it does not.
            got = t2 >= 0
            got[got] = outside_distance(self.v, self.t, t2[got], om[got], dm[got]) <= self.tol
            dist[miss[got]], tri[miss[got]] = d2[got], t2[got]
            won.append(miss[got])
            miss, om = miss[~got], om[~got]
        return np.concatenate(won) if won else np.zeros(0, np.int64)

    def _misses_near_hull(self, o, d, max_dist, tri, reach=None):
        """The misses worth a hull cast. Model no more than the scene needs: a miss
        that cannot reach any hull box (e.g. a sky ray over everything) is a real miss,
        with no hull cast. ``reach``: the rays that may reach the hull, if known."""
        if reach is not None:
            return reach[tri[reach] < 0]
        miss = np.nonzero(tri < 0)[0]
        if len(miss) == 0:
            return miss
        return miss[self.may_reach_hull(_take(o, miss), d[miss], max_dist,
                                        self.octant_boxes(o))]

    def octant_boxes(self, origins):
        """Per octant of directions (bit k set: negative along axis k), the union of the
        hull boxes a ray from any of ``origins`` ((1, 3) or (N, 3)) moving that way
        can reach (those ahead of the origins' bounds along each axis): ((8, 6) lo xyz
        hi xyz, (8,) int32 1 where the octant has any box)."""
        lo_o, hi_o = column_bounds(origins)
        # The table depends on the origins' bounds alone: a still sensor's frames (and a
        # study's candidates on one mount) ask for the same one (read-only, shared).
        key = lo_o.tobytes() + hi_o.tobytes()
        if self._octants[0] == key:
            return self._octants[1]
        # (3, B) per axis, so that every reduction below runs along contiguous rows
        box_lo, box_hi = np.ascontiguousarray(self.box_lo.T), np.ascontiguousarray(self.box_hi.T)
        ahead_lo = box_hi > lo_o[:, None]   # reachable moving + along the axis
        ahead_hi = box_lo < hi_o[:, None]   # reachable moving - along the axis
        # (8, B): box b lies ahead along every axis of octant code (all octants at once:
        # a loop over them took half a millisecond a cast)
        sel = np.where(_OCTANT_NEG[:, :, None], ahead_hi[None], ahead_lo[None]).all(axis=1)
        has = sel.any(axis=1).astype(np.int32)
        lo = np.where(sel[:, None, :], box_lo[None], np.inf).min(axis=2)
        hi = np.where(sel[:, None, :], box_hi[None], -np.inf).max(axis=2)
        boxes = np.where(has[:, None] != 0, np.concatenate([lo, hi], axis=1), 0.0)
        boxes.flags.writeable = has.flags.writeable = False
        self._octants = (key, (boxes, has))
        return boxes, has

    def may_reach_hull(self, origins, directions, max_dist, table=None):
        """(M,) bool: False for rays (from ``origins``, (1, 3) or (M, 3)) that surely
        meet no hull box within ``max_dist``, True for the others (conservative: a
        True ray may still miss every box): a ray that misses its octant's union box
        (``octant_boxes``) misses every box in it. From a sensor above the ground,
        the rays to the sky meet only what stands taller than the sensor, so most are
        answered without a cast. The compiled loop does the same test, operation by
        operation (embree_loop.c: may_reach_hull)."""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        boxes, has = self.octant_boxes(o) if table is None else table
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        neg = d < 0
        code = neg[:, 0] | (neg[:, 1] << 1) | (neg[:, 2] << 2)
        near, far = np.full(len(d), -np.inf), np.full(len(d), np.inf)
        # Axis by axis on columns: reductions over the short axis of an (M, 3) array
        # are many times slower.
        for k in range(3):
            _clip_slab(boxes[:, k].take(code) - o[:, k], boxes[:, 3 + k].take(code) - o[:, k],
                       d[:, k], near, far)
        return (has.take(code) != 0) & (near <= far) & (far >= 0) & (near <= max_dist)

    def _starts_inside(self, o):
        """True unless every origin of ``o`` ((1, 3) or (N, 3): a driving sensor's, one
        per ray) lies outside every hull box (then a ray's first hull hit is where it
        enters one). Per-ray origins are judged by their bounds: when the box around
        them all meets no hull box, none of them lies in one (a sensor driving over a
        road keeps its limit; before, every per-ray origin counted as inside, and a
        driving Pandar64 re-cast each ray that hit a car: 27,585 rays of frame 40
        through the sample traffic)."""
        lo, hi = column_bounds(o)
        return bool(np.any(np.all((self.box_lo <= hi) & (lo <= self.box_hi), axis=1)))
