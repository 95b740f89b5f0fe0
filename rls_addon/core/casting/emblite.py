"""Ray casting on Intel Embree 4 through the ``pyemblite`` wheel: the backend of the
macOS zips (arm64 and x86-64), where PyPI has no ``embreex`` 4 wheel. pyemblite links
Embree 4 statically into its Cython modules (no library to bind, so no packets and
no compiled loop) and casts one ray at a time on one core; measured on Linux with the
same package (docs/platforms.md) a Pandar64 frame's cast takes 25 ms against 400 ms
with BVHTree, from a 19 MB (arm64) or 11 MB (x86-64) wheel that needs only numpy.

    caster = EmbliteCaster(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (1,3) or (N,3), directions (N,3) unit, max_dist)

``dist`` float64 (inf for a miss), ``tri`` int64 (-1 for a miss). Embree works in
float32; the engine recomputes every range exactly in float64 afterwards
(``casting.refine_hits``), so Embree only decides which triangle a ray hits.
``pyemblite`` is imported when first needed, so the core imports without it.
"""

import numpy as np

from ..errors import CastingError
from .base import CasterBase, OptionalLibrary

def _load():
    """(rtcore_scene, TriangleMesh) of pyemblite."""
    from pyemblite import rtcore_scene
    from pyemblite.mesh_construction import TriangleMesh

    return rtcore_scene, TriangleMesh


_LIBRARY = OptionalLibrary(_load)
_import = _LIBRARY.get
available = _LIBRARY.available            # True when pyemblite can be imported
unavailable_reason = _LIBRARY.unavailable_reason


class EmbliteCaster(CasterBase):
    """Embree 4 through pyemblite's ``EmbreeScene.run``: closest hits, one core."""

    name = "embree"

    def __init__(self, vertices, triangles):
        mods = _import()
        if isinstance(mods, Exception):
            raise CastingError(f"pyemblite is not available ({unavailable_reason()})")
        rtcore_scene, TriangleMesh = mods
        v = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).reshape(-1, 3),
                                 dtype=np.float32)
        t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if len(t) and (t.min() < 0 or t.max() >= len(v)):
            raise CastingError("triangle indices out of range")
        self.triangle_count = len(t)
        self._scene = None
        if len(t):
            self._scene = rtcore_scene.EmbreeScene()
            TriangleMesh(self._scene, v, np.ascontiguousarray(t, dtype=np.int32))
            # Embree builds its BVH at the first query: here, so that building a
            # caster costs what it costs and the first cast does not.
            self._run(np.zeros((1, 3), np.float32), np.array([[1.0, 0, 0]], np.float32), 1.0)

    def describe(self):
        return "embree (pyemblite, 1 thread)"

    def _run(self, o, d, tfar):
        return self._scene.run(o, d, dists=np.full(len(d), tfar, np.float32), output=1)

    def cast(self, origins, directions, max_dist):
        d = np.ascontiguousarray(np.asarray(directions, dtype=np.float64).reshape(-1, 3),
                                 dtype=np.float32)
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3).astype(np.float32)
        n = d.shape[0]
        if o.shape[0] not in (1, n):
            raise CastingError("origins must be (1, 3) or one per direction")
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, dtype=np.int64)
        if n == 0 or self._scene is None:
            return dist, tri
        res = self._run(np.ascontiguousarray(np.broadcast_to(o, d.shape)), d,
                        np.float32(min(float(max_dist), 3.0e38)))
        hit = res["geomID"] != -1
        dist[hit] = res["tfar"][hit]
        tri[hit] = res["primID"][hit]
        return dist, tri

    def close(self):
        self._scene = None
