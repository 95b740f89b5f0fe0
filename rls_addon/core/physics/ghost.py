"""Ghost points from specular surfaces (glass, water, polished metal, traffic signs).

A beam that hits a mirror-like surface at distance a may travel on along the
reflected direction r = u - 2(u.n)n, hit a second object at distance b, and return
the same way; the sensor then reports a point at a + b along the original beam: the
mirror image of the second object. Which glossy hits become ghosts is decided per
material by a ghost ratio (default 0.5, as the paper) with the scan's generator.
"""

import ctypes
from dataclasses import dataclass

import numpy as np

from ..native.kernels import Kernel
from ..labels import NAME_TO_ID
from ..native.vectors import row_dot

# Smoothness per semantic class (0..1), after the paper's target-reflector library;
# a surface is glossy when its smoothness exceeds SMOOTHNESS_THRESHOLD.
LABEL_SMOOTHNESS = {"glass": 0.9, "water": 0.9, "traffic_sign": 0.8, "metal": 0.7}
SMOOTHNESS_THRESHOLD = 0.5


def glossy_labels(table=None, threshold=SMOOTHNESS_THRESHOLD):
    """Label ids whose smoothness exceeds the threshold."""
    table = LABEL_SMOOTHNESS if table is None else table
    return {NAME_TO_ID[name] for name, s in table.items() if s > threshold and name in NAME_TO_ID}


def glossy_tables(geometry, label_ids):
    """(per-object glossy flag, per-material glossy flag, per-material ghost ratio): a
    surface is glossy when its material is, or its object's label is in
    ``label_ids``. Computed once per geometry."""
    key = ("glossy_objects", frozenset(label_ids))
    obj = geometry._cache.get(key)
    if obj is None:
        obj = geometry._cache[key] = np.array(
            [o.label in label_ids for o in geometry.objects] or [False], dtype=bool)
    return (obj, geometry.material_field("glossy").astype(bool),
            geometry.material_field("ghost_ratio").astype(np.float64))


def reflect(u, n):
    """Mirror directions r = u - 2 (u.n) n, row-wise."""
    return u - (2.0 * row_dot(u, n))[:, None] * n


def bounce_origins(points, u, n, distance):
    """Start points for reflected rays: the hit point moved off the surface, towards the
    side the beam came from, by a scale-aware epsilon (a few float32 ulps of the
    distance travelled), so that a reflected ray never re-hits its own surface."""
    side = np.where((row_dot(u, n) < 0)[:, None], n, -n)
    eps = 1e-6 + 4e-6 * np.asarray(distance)[:, None]
    return points + side * eps


@dataclass
class Aim:
    """The rays whose glossy return sends a beam on (``aim``)."""

    glossy_hits: int     # valid returns on glossy surfaces
    chosen: np.ndarray   # the rays that bounce, ascending
    a: np.ndarray        # their range to the mirror
    r: np.ndarray        # reflected directions
    p: np.ndarray        # mirror points
    start: np.ndarray    # where the reflected beams start (p lifted off the mirror)


def aim(valid, surface, tables, uniforms, dist, dirs, normals, origins):
    """Which valid returns on glossy surfaces bounce (their ghost ``uniforms`` below the
    material's ghost ratio; ``tables``: ``glossy_tables``) and where their reflected
    beams go. ``origins``: one row, or one per ray. In C (native/c/ghosts.c) where it is
    built, else ``aim_numpy``: the same bytes."""
    fn = AIM.get() if compiled else None
    if fn is None:
        return aim_numpy(valid, surface, tables, uniforms, dist, dirs, normals, origins)
    obj_glossy, mat_glossy, mat_ratio = tables
    n = len(dist)
    keep = [np.ascontiguousarray(x, t) for x, t in (
        (valid, np.bool_), (surface, np.int32), (uniforms, np.float64),
        (dist, np.float64), (dirs, np.float64), (normals, np.float64),
        (origins, np.float64), (mat_glossy, np.bool_), (mat_ratio, np.float64))]
    obj = np.ascontiguousarray(obj_glossy, np.bool_) if obj_glossy.any() else None
    out = (np.empty(n, np.int64), np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
           np.empty((n, 3)))
    p = [x.ctypes.data for x in keep]
    args = _AimArgs(n, p[0], p[1], None if obj is None else obj.ctypes.data,
                    0 if obj is None else len(obj), p[7], p[8], len(keep[7]), p[2], p[3],
                    p[4], p[5], p[6], int(keep[6].shape[0] == n and n > 1), 0,
                    *(x.ctypes.data for x in out))
    m = fn(ctypes.byref(args))
    if m < 0:
        raise ValueError("a surface id is outside the scene's object or material table")
    return Aim(int(args.glossy_hits), *(x[:m] for x in out))


def aim_numpy(valid, surface, tables, uniforms, dist, dirs, normals, origins):
    """The reference of ``aim``."""
    obj_glossy, mat_glossy, mat_ratio = tables
    obj, mat = surface[:, 0], surface[:, 1]
    glossy = mat_glossy.take(mat)  # take: a third of fancy indexing's time
    if obj_glossy.any():
        glossy |= obj_glossy.take(obj)
    cand = np.nonzero(glossy & valid)[0]
    c = cand[uniforms[cand] < mat_ratio[mat[cand]]] if len(cand) else cand
    a = dist[c]
    uc, nc = dirs.take(c, axis=0), normals.take(c, axis=0)
    o = origins if origins.shape[0] == 1 else origins[c]
    p = o + uc * a[:, None]
    return Aim(len(cand), c, a, reflect(uc, nc), p, bounce_origins(p, uc, nc, a))


def land(bounce, b, tri, n2, rmax, valid, dist, normals, surface, reflectivity):
    """Turn the bounces whose reflected beam found a surface (at ``b`` along it, triangle
    ``tri`` >= 0, normal ``n2``) within ``rmax`` in total into ghosts: ``dist`` becomes
    the total path a + b measured from the mirror point itself, ``normals`` the second
    surface's; the other bounced rays leave ``valid``. Updates those three in place;
    returns (which bounces became ghosts, a per-ray uint8 ghost flag, their last legs'
    directions, their mirrors' reflectivity). In C (native/c/ghosts.c) where it is built,
    else ``land_numpy``: the same bytes."""
    fn = LAND.get() if compiled else None
    arrays = (valid, dist, normals)
    if fn is None or not all(x.flags.c_contiguous for x in arrays) \
            or valid.dtype != np.bool_ or dist.dtype != np.float64 \
            or normals.dtype != np.float64:
        return land_numpy(bounce, b, tri, n2, rmax, valid, dist, normals, surface,
                          reflectivity)
    m = len(bounce.chosen)
    keep = [np.ascontiguousarray(x, t) for x, t in (
        (bounce.chosen, np.int64), (bounce.a, np.float64), (bounce.r, np.float64),
        (bounce.p, np.float64), (bounce.start, np.float64), (b, np.float64),
        (tri, np.int64), (n2, np.float64), (surface, np.int32),
        (reflectivity, np.float64))]
    ghost = np.zeros(len(dist), np.uint8)
    found, last, mirror = np.empty(m, np.int64), np.empty((m, 3)), np.empty(m)
    p = [x.ctypes.data for x in keep]
    args = _LandArgs(m, *p[:8], float(rmax), valid.ctypes.data, dist.ctypes.data,
                     normals.ctypes.data, ghost.ctypes.data, p[8], p[9], len(keep[9]),
                     found.ctypes.data, last.ctypes.data, mirror.ctypes.data)
    k = fn(ctypes.byref(args))
    if k < 0:
        raise ValueError("a mirror's material is outside the scene's material table")
    return found[:k], ghost, last[:k], mirror[:k]


def land_numpy(bounce, b, tri, n2, rmax, valid, dist, normals, surface, reflectivity):
    """The reference of ``land``."""
    found = tri >= 0
    # The second leg measured from the mirror point itself, not the lifted start.
    x = bounce.start + bounce.r * np.where(found, b, 0)[:, None] - bounce.p
    b = np.where(found, np.sqrt(row_dot(x, x)), b)
    found &= bounce.a + b <= rmax
    fi = np.nonzero(found)[0]
    g = bounce.chosen[fi]
    valid[bounce.chosen[~found]] = False
    mirror = reflectivity[surface[g, 1]]
    dist[g] = bounce.a[fi] + b[fi]
    normals[g] = n2.take(fi, axis=0)
    ghost = np.zeros(len(dist), np.uint8)
    ghost[g] = 1
    return fi, ghost, bounce.r.take(fi, axis=0), mirror


class _AimArgs(ctypes.Structure):
    """``aim_t`` of native/c/ghosts.c."""

    _fields_ = [("n", ctypes.c_int64), ("valid", ctypes.c_void_p),
                ("surface", ctypes.c_void_p), ("obj_glossy", ctypes.c_void_p),
                ("n_obj", ctypes.c_int64), ("mat_glossy", ctypes.c_void_p),
                ("mat_ratio", ctypes.c_void_p), ("n_mat", ctypes.c_int64),
                ("uniforms", ctypes.c_void_p), ("dist", ctypes.c_void_p),
                ("dirs", ctypes.c_void_p), ("normals", ctypes.c_void_p),
                ("origins", ctypes.c_void_p), ("per_ray_origins", ctypes.c_int64),
                ("glossy_hits", ctypes.c_int64), ("chosen", ctypes.c_void_p),
                ("a", ctypes.c_void_p), ("r", ctypes.c_void_p), ("p", ctypes.c_void_p),
                ("start", ctypes.c_void_p)]


class _LandArgs(ctypes.Structure):
    """``land_t`` of native/c/ghosts.c."""

    _fields_ = [("m", ctypes.c_int64), ("chosen", ctypes.c_void_p),
                ("a", ctypes.c_void_p), ("r", ctypes.c_void_p), ("p", ctypes.c_void_p),
                ("start", ctypes.c_void_p), ("b", ctypes.c_void_p),
                ("tri", ctypes.c_void_p), ("n2", ctypes.c_void_p), ("rmax", ctypes.c_double),
                ("valid", ctypes.c_void_p), ("dist", ctypes.c_void_p),
                ("normals", ctypes.c_void_p), ("ghost", ctypes.c_void_p),
                ("surface", ctypes.c_void_p), ("reflectivity", ctypes.c_void_p),
                ("n_mat", ctypes.c_int64), ("found", ctypes.c_void_p),
                ("last_leg", ctypes.c_void_p), ("mirror", ctypes.c_void_p)]


NATIVE_GHOSTS_ABI = 1
AIM = Kernel("rls_ghost_aim", "rls_ghosts_abi", NATIVE_GHOSTS_ABI,
             [ctypes.POINTER(_AimArgs)], ctypes.c_int64)
LAND = Kernel("rls_ghost_land", "rls_ghosts_abi", NATIVE_GHOSTS_ABI,
              [ctypes.POINTER(_LandArgs)], ctypes.c_int64)
# Off: every frame aims and lands its bounces in numpy (the reference the C code is
# tested against).
compiled = True
