"""Brute-force ray casting in numpy: exact in float64, O(rays x triangles); the
reference the other backends are tested against, and the caster of core tests."""

import numpy as np

from .base import CasterBase


class NumpyCaster(CasterBase):
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
