"""Ray casting backends share one small interface:

    caster = factory(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (N,3) float64, directions (N,3) float64 unit, max_dist)

``dist`` is float64 (inf where nothing was hit), ``tri`` int64 (-1 for a miss) indexes
the triangles given to the factory. The Blender layer provides the BVHTree backend;
this module holds a brute-force numpy reference, exact in float64, for tests and tiny
scenes.
"""

import numpy as np


class NumpyCaster:
    """Brute-force Moller-Trumbore intersection over all triangles, in chunks.

    Costs O(rays x triangles): meant as an exact reference for tests, not for scenes.
    Edges and vertices are closed (a ray through a shared edge hits one of the faces).
    """

    name = "numpy"

    def __init__(self, vertices, triangles, chunk=2_000_000):
        v = np.asarray(vertices, dtype=np.float64)
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.v0 = v[t[:, 0]]
        self.e1 = v[t[:, 1]] - self.v0
        self.e2 = v[t[:, 2]] - self.v0
        self.chunk = chunk

    def cast(self, origins, directions, max_dist):
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        n = d.shape[0]
        if o.shape[0] == 1 and n != 1:
            o = np.broadcast_to(o, d.shape)
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, dtype=np.int64)
        m = self.v0.shape[0]
        if m == 0 or n == 0:
            return dist, tri
        step = max(1, self.chunk // m)
        for s in range(0, n, step):
            dd, oo = d[s:s + step, None, :], o[s:s + step, None, :]
            p = np.cross(dd, self.e2[None])
            det = np.einsum("ijk,jk->ij", p, self.e1)
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / det
                tv = oo - self.v0[None]
                u = np.einsum("ijk,ijk->ij", tv, p) * inv
                q = np.cross(tv, self.e1[None])
                w = np.einsum("ijk,ik->ij", q, d[s:s + step]) * inv
                t = np.einsum("ijk,jk->ij", q, self.e2) * inv
                eps = 1e-12
                ok = (np.abs(det) > 1e-300) & (u >= -eps) & (w >= -eps) & (u + w <= 1 + eps)
                ok &= (t > 0) & (t <= max_dist)
            t = np.where(ok, t, np.inf)
            j = np.argmin(t, axis=1)
            best = t[np.arange(t.shape[0]), j]
            hit = np.isfinite(best)
            dist[s:s + step] = best
            tri[s:s + step] = np.where(hit, j, -1)
        return dist, tri


def triangle_planes(vertices, triangles):
    """Plane of each triangle as a (T, 4) float64 table: unit normal (nx, ny, nz) and
    offset n . v0 (degenerate triangles get NaN rows)."""
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    v0 = vertices[t[:, 0]]
    out = np.empty((len(t), 4))
    n = out[:, :3]
    n[:] = np.cross(vertices[t[:, 1]] - v0, vertices[t[:, 2]] - v0)
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.linalg.norm(n, axis=1, keepdims=True)
    out[:, 3] = np.einsum("ij,ij->i", n, v0)
    return out


# Below this |cos| between ray and plane the float64 plane answer is ill-conditioned
# (grazing): the backend's own distance is kept (as the compiled Embree loop does).
GRAZING = 1e-6


def refine_hits(vertices, triangles, origins, directions, dist, tri, planes=None):
    """Recompute hit distances exactly in float64 against each hit triangle's plane.

    Backends that work in float32 (BVHTree, Embree) then only decide *which*
    triangle was hit; the range itself is exact. ``planes`` is the triangles'
    ``triangle_planes`` table when precomputed. Returns (dist, unit normals) with the
    normal of every hit triangle (zeros for misses).
    """
    dist = np.array(dist, dtype=np.float64, copy=True)
    normals = np.zeros((dist.shape[0], 3))
    hit = np.nonzero(tri >= 0)[0]
    if len(hit) == 0:
        return dist, normals
    th = tri[hit]
    pl = triangle_planes(vertices, np.asarray(triangles, np.int64)[th]) if planes is None \
        else planes[th]
    n, off = pl[:, :3], pl[:, 3]
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = directions[hit]
    denom = np.einsum("ij,ij->i", n, d)
    no = (n @ o[0]) if o.shape[0] == 1 else np.einsum("ij,ij->i", n, o[hit])
    with np.errstate(divide="ignore", invalid="ignore"):
        exact = (off - no) / denom
    # Keep the backend's value where the plane is nearly parallel to the ray (grazing),
    # where the float64 answer is ill-conditioned anyway.
    use = np.isfinite(exact) & (np.abs(denom) > GRAZING) & (exact > 0)
    dist[hit[use]] = exact[use]
    normals[hit] = n
    return dist, normals


def cast_exact(caster, origins, directions, max_dist, planes, order=None):
    """Cast and refine: (dist, tri, unit normals), every hit's range recomputed in
    float64 against its plane (``planes`` from ``triangle_planes`` of the caster's
    triangles). Backends that can fuse the two (``cast_refined``, the compiled Embree
    loop) do it while casting; the others are refined here with ``refine_hits``.
    ``order``: an optional permutation to trace the rays in (a coherent order is
    faster where the backend traces rays in packets; the results do not change)."""
    fused = getattr(caster, "cast_refined", None)
    got = fused(origins, directions, max_dist, planes, order) if fused is not None else None
    if got is not None:
        return got
    dist, tri = caster.cast(origins, directions, max_dist)
    dist, normals = refine_hits(None, None, origins, directions, dist, tri, planes)
    return dist, tri, normals


# Generic (irrational-ish) vectors used to pick a perpendicular nudge for each retry.
_NUDGE_AXES = np.array([[0.7548776662, 0.5698402910, 0.3247179572],
                        [-0.2306, 0.8715, -0.4330],
                        [0.5773, -0.2113, 0.7887]])
_NUDGE_SCALES = (64.0,)  # in units of 1e-6 x (scene extent)


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
    tv = vertices[triangles]
    tmin, tmax = tv.min(axis=1), tv.max(axis=1)
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


def outside_distance(vertices, triangles, tri, origins, directions):
    """How far (metres) each ray's crossing of its triangle's plane lies outside that
    triangle (0 inside; inf for rays parallel to the plane or crossing it behind the
    origin). float64."""
    t = triangles[tri]
    a, b, c = vertices[t[:, 0]], vertices[t[:, 1]], vertices[t[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    denom = np.einsum("ij,ij->i", n, directions)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.einsum("ij,ij->i", n, a - origins) / denom
        x = origins + directions * s[:, None]
        out = np.zeros(len(tri))
        for p, q in ((a, b), (b, c), (c, a)):
            m = np.cross(n, q - p)
            m /= np.linalg.norm(m, axis=1, keepdims=True)
            out = np.maximum(out, -np.einsum("ij,ij->i", x - p, m))
    return np.where(np.isfinite(out) & (s > 0), out, np.inf)


class WatertightCaster:
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
        self.primary = getattr(factory, "behind_watertight", factory)(vertices, triangles)
        self.name = getattr(self.primary, "name", "caster")
        v = np.asarray(vertices, np.float64)
        tv = v[np.asarray(triangles, np.int64)]
        lo_all, hi_all = tv.reshape(-1, 3).min(0), tv.reshape(-1, 3).max(0)
        self.extent = float(np.linalg.norm(hi_all - lo_all)) + 1.0
        groups = np.zeros(len(triangles), np.int64) if groups is None else groups
        cell = max(self.extent / 32.0, 1.0) if cell is None else float(cell)
        lo, hi = cluster_boxes(v, np.asarray(triangles, np.int64), groups, cell)
        pad = 1e-5 * self.extent
        self.box_lo, self.box_hi = lo - pad, hi + pad
        hv, ht = box_triangles(self.box_lo, self.box_hi)
        self.hull = factory(hv, ht)
        self.v, self.t = v, np.asarray(triangles, np.int64)
        self.tol = 1e-6 * self.extent
        self.retried = 0

    def cast(self, origins, directions, max_dist):
        d = np.asarray(directions, np.float64)
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        dist, tri = self.primary.cast(o, d, max_dist)
        self._recheck(o, d, max_dist, dist, tri)
        return dist, tri

    def cast_refined(self, origins, directions, max_dist, planes, order=None):
        """``cast`` with every hit refined (see ``cast_exact``): the primary cast is
        refined by its backend, the few rays won back by the re-check here."""
        d = np.asarray(directions, np.float64)
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        dist, tri, normals = cast_exact(self.primary, o, d, max_dist, planes, order)
        self.win_back(o, d, max_dist, planes, dist, tri, normals)
        return dist, tri, normals

    def win_back(self, o, d, max_dist, planes, dist, tri, normals, limit=None):
        """Re-check the misses (``tri`` -1) of a refined cast of the primary build and
        write what they find, refined, into ``dist``, ``tri`` and ``normals``;
        returns the indices of the rays won back. ``limit`` (per ray): only a crack
        nearer than this matters (a ray that hit something else there)."""
        got = self._recheck(o, d, max_dist, dist, tri, limit)
        if len(got):
            dist[got], normals[got] = refine_hits(None, None, o if o.shape[0] == 1 else o[got],
                                                  d[got], dist[got], tri[got], planes)
        return got

    def _recheck(self, o, d, max_dist, dist, tri, limit=None):
        """Re-cast the misses that may have slipped through a crack (see the class
        docstring), writing what they find into ``dist`` and ``tri``; returns the
        indices of the rays won back. With ``limit`` (per ray), a miss whose path
        meets no hull box before its limit is not re-cast."""
        won = []
        miss = np.nonzero(tri < 0)[0]
        if len(miss) == 0:
            return np.zeros(0, np.int64)
        om = np.broadcast_to(o, d.shape)[miss]
        entry, inside = self.hull.cast(om, d[miss], max_dist)
        keep = inside >= 0
        if limit is not None and not self._starts_inside(o):
            keep &= entry <= limit[miss]
        miss, om = miss[keep], om[keep]
        for axis, scale in zip(_NUDGE_AXES, _NUDGE_SCALES):
            if len(miss) == 0:
                break
            self.retried += len(miss)
            dm = d[miss]
            perp = np.cross(dm, axis)
            perp /= np.linalg.norm(perp, axis=1, keepdims=True)
            nudge = scale * 1e-6 * self.extent
            d2, t2 = self.primary.cast(om + perp * nudge, dm, max_dist)
            # Keep a nudged hit only if the *original* ray passes the hit triangle within
            # float32 noise: through a crack it does, past a silhouette it does not.
            got = t2 >= 0
            got[got] = outside_distance(self.v, self.t, t2[got], om[got], dm[got]) <= self.tol
            dist[miss[got]], tri[miss[got]] = d2[got], t2[got]
            won.append(miss[got])
            miss, om = miss[~got], om[~got]
        return np.concatenate(won) if won else np.zeros(0, np.int64)

    def _starts_inside(self, o):
        """True unless ``o`` is one origin outside every hull box (then a ray's first
        hull hit is where it enters one; per-ray origins are not checked)."""
        if o.shape[0] != 1:
            return True
        return bool(np.any(np.all((self.box_lo <= o[0]) & (o[0] <= self.box_hi), axis=1)))
