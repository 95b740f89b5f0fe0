"""Ray casting on Open3D's ``RaycastingScene`` (``open3d.t.geometry``), which wraps
Intel Embree 3 and casts on all cores: used where a user has Open3D and neither Embree
wheel (docs/platforms.md: measured on Linux it casts a Pandar64 frame 25x faster than
BVHTree; the macOS zips bundle pyemblite instead, for the weight of Open3D's wheels).

    caster = Open3DCaster(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (1,3) or (N,3), directions (N,3) unit, max_dist)

``dist`` float64 (inf for a miss), ``tri`` int64 (-1 for a miss). Open3D works in
float32 and casts every ray to infinity; a hit beyond ``max_dist`` is a miss (Embree's
``tfar`` does the same), and the engine recomputes every range exactly in float64
afterwards (``casting.refine_hits``), so Open3D only decides which triangle is hit.
``open3d`` is imported when a caster is built (about 0.6 s, once), so the core still
imports without it.
"""

import numpy as np

from ..errors import CastingError
from .base import CasterBase, OptionalLibrary

_INVALID = np.uint32(0xFFFFFFFF)  # RaycastingScene.INVALID_ID


def _load():
    """The ``open3d`` module, with the API this backend needs."""
    import open3d

    open3d.t.geometry.RaycastingScene  # noqa: B018 (fails early on an old Open3D)
    return open3d


_LIBRARY = OptionalLibrary(_load)
_import = _LIBRARY.get
available = _LIBRARY.available  # True when Open3D and its RaycastingScene import
unavailable_reason = _LIBRARY.unavailable_reason


class Open3DCaster(CasterBase):
    """Open3D's ``RaycastingScene`` (Embree 3 inside), closest hits on all cores.

    threads  threads for each cast (default 0: all the cores Open3D sees)
    """

    name = "open3d"

    def __init__(self, vertices, triangles, threads=None):
        o3d = _import()
        if isinstance(o3d, Exception):
            raise CastingError(f"Open3D is not available ({unavailable_reason()})")
        self._o3d = o3d
        v = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).reshape(-1, 3),
                                 dtype=np.float32)
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(t) and (t.min() < 0 or t.max() >= len(v)):
            raise CastingError("triangle indices out of range")
        self.triangle_count = len(t)
        self.threads = int(threads) if threads else 0
        self._scene = None
        if len(t):
            self._scene = o3d.t.geometry.RaycastingScene()
            self._scene.add_triangles(
                o3d.core.Tensor.from_numpy(v),
                o3d.core.Tensor.from_numpy(np.ascontiguousarray(t, dtype=np.uint32)))

    def describe(self):
        threads = "all cores" if self.threads == 0 else \
            f"{self.threads} thread{'s' if self.threads != 1 else ''}"
        return f"open3d (RaycastingScene, Embree inside, {threads})"

    def cast(self, origins, directions, max_dist):
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        n = d.shape[0]
        if o.shape[0] not in (1, n):
            raise CastingError("origins must be (1, 3) or one per direction")
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, dtype=np.int64)
        if n == 0 or self._scene is None:
            return dist, tri
        rays = np.empty((n, 6), np.float32)
        rays[:, :3] = o
        rays[:, 3:] = d
        got = self._scene.cast_rays(self._o3d.core.Tensor.from_numpy(rays),
                                    nthreads=self.threads)
        t_hit = got["t_hit"].numpy()
        prim = got["primitive_ids"].numpy()
        hit = (got["geometry_ids"].numpy() != _INVALID) & np.isfinite(t_hit) \
            & (t_hit <= np.float32(min(float(max_dist), 3.0e38)))
        dist[hit] = t_hit[hit]
        tri[hit] = prim[hit]
        return dist, tri

    def close(self):
        self._scene = None
