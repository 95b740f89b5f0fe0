"""What every ray-casting backend must do, what it may do, and the float64 refinement
that makes every backend's ranges exact.

A backend is a class (the *factory*) built on one set of triangles:

    caster = Backend(vertices (V,3) float64, triangles (T,3) int)
    dist, tri = caster.cast(origins (1,3) or (N,3) float64, directions (N,3) unit, max_dist)

``dist`` is float64 (inf where nothing was hit), ``tri`` int64 (-1 for a miss) indexes
the triangles given to the constructor. That is all a backend *must* do (``Caster``).
What it *may* do is declared on ``CasterBase``, whose defaults say "not offered":

- ``start_refined``: cast and refine every hit in float64 without Python (the compiled
  Embree loop), returning a function that waits for the result; else None and the
  engine refines in numpy (``cast_exact``).
- ``behind_watertight``: the build to use behind ``WatertightCaster``, which re-checks
  misses itself (Embree drops its slower robust mode there).
- ``instances``: a class that traces several casters of this backend as instances in
  one traversal, with per-ray times (Embree); None: each moving object is cast on its
  own (``bodies.RigidBodies``).

Kept static casts need nothing from a backend: ``bodies.PreparedScene`` keeps its last
cast of a still sensor's rays and gives it back.

The backends: ``numpy_caster.NumpyCaster`` (brute force, exact, for tests and tiny
scenes), ``bvhtree.BVHCaster`` (Blender's BVHTree), ``embree.EmbreeCaster`` (Intel
Embree with the compiled loop in ``native/``), ``emblite.EmbliteCaster`` (Embree 4 from
the pyemblite wheel, for macOS), ``open3d_caster.Open3DCaster`` (Open3D's
RaycastingScene, where a user has it); ``casting.caster_factory`` picks one by name and
``casting.backend_status`` says which and why.
"""

import threading
from typing import Callable, Protocol

import numpy as np

from ..native.vectors import row_dot


class Caster(Protocol):
    """The one thing every backend must do (see the module docstring)."""

    name: str

    def cast(self, origins: np.ndarray, directions: np.ndarray,
             max_dist: float) -> tuple[np.ndarray, np.ndarray]: ...


class CasterBase:
    """Base of the backends: ``cast`` to implement, the optional abilities declared with
    their "not offered" defaults (see the module docstring)."""

    name = "caster"
    instances = None  # class tracing casters of this backend as moving instances, or None
    # True where every ray costs a Python call (BVHTree): the watertight wrapper then
    # casts only the rays that may reach its hull (see WatertightCaster.rows_worth_casting)
    skip_sure_misses = False

    def cast(self, origins, directions, max_dist):
        raise NotImplementedError

    @classmethod
    def behind_watertight(cls, vertices, triangles):
        """The build ``WatertightCaster`` casts through (default: the usual one)."""
        return cls(vertices, triangles)

    def start_refined(self, origins, directions, max_dist, planes,
                      order=None) -> Callable | None:
        """Start a cast whose hits are refined in float64 against ``planes`` (see
        ``cast_exact``); a function giving (dist, tri, unit normals), or None when
        this backend cannot (then ``cast_exact`` refines in numpy)."""
        return None

    def describe(self):
        """The backend and how it runs, for reports."""
        return self.name

    @classmethod
    def configured(cls, **options):
        """This backend with fixed constructor options, as a factory of its own (e.g.
        ``EmbreeCaster.configured(mode="embreex")``); options given at a build win
        (e.g. ``behind_watertight``'s)."""
        return type(f"{cls.__name__}Configured", (cls,), {
            "__init__": lambda self, v, t, **more: cls.__init__(self, v, t,
                                                                 **{**options, **more})})


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
    exact, use = plane_ranges(pl, origins, directions, hit)
    # Keep the backend's value where the plane is nearly parallel to the ray (grazing),
    # where the float64 answer is ill-conditioned anyway.
    dist[hit[use]] = exact[use]
    normals[hit] = pl[:, :3]
    return dist, normals


def plane_ranges(planes, origins, directions, rows):
    """Ranges along rays ``rows`` (of ``origins`` (1, 3) or (N, 3), ``directions``) to
    their planes (``planes``: a ``triangle_planes`` row per ray), and where they are
    usable (False where the ray grazes the plane or meets it behind the origin)."""
    n, off = planes[:, :3], planes[:, 3]
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    o = o if o.shape[0] == 1 else o[rows]
    d = directions[rows]
    # Summed in the compiled loop's order (native/c/embree_loop.c), for the same bits.
    denom = row_dot(n, d)
    no = row_dot(n, o)
    with np.errstate(divide="ignore", invalid="ignore"):
        exact = (off - no) / denom
    return exact, np.isfinite(exact) & (np.abs(denom) > GRAZING) & (exact > 0)


def cast_exact(caster, origins, directions, max_dist, planes, order=None):
    """Cast and refine: (dist, tri, unit normals), every hit's range recomputed in
    float64 against its plane (``planes`` from ``triangle_planes`` of the caster's
    triangles). Backends that can fuse the two (``start_refined``, the compiled Embree
    loop) do it while casting; the others are refined here with ``refine_hits``.
    ``order``: an optional permutation to trace the rays in (a coherent order is
    faster where the backend traces rays in packets; the results do not change)."""
    pending = caster.start_refined(origins, directions, max_dist, planes, order)
    if pending is not None:
        return pending()
    dist, tri = caster.cast(origins, directions, max_dist)
    dist, normals = refine_hits(None, None, origins, directions, dist, tri, planes)
    return dist, tri, normals




class OptionalLibrary:
    """A backend's optional library, imported on first use, once, by any thread:
    ``get()`` gives what ``load()`` returned or the exception it raised (an ImportError,
    a broken binary wheel's OSError...), so the core imports without the library."""

    def __init__(self, load):
        self._load, self._lock, self._got = load, threading.Lock(), None

    def get(self):
        with self._lock:
            if self._got is None:
                try:
                    self._got = (self._load(),)
                except Exception as exc:  # noqa: BLE001 (said by unavailable_reason)
                    self._got = (exc,)
            return self._got[0]

    def available(self):
        """True when the library imports."""
        return not isinstance(self.get(), Exception)

    def unavailable_reason(self):
        """Why ``available()`` is False ('' when it is True)."""
        got = self.get()
        return f"{type(got).__name__}: {got}" if isinstance(got, Exception) else ""
