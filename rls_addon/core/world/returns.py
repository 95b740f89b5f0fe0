"""What each ray of a static scene's cast brought back: whether it returns a point, and
the (object, material) ids of the surface it hit.

In C (``native/c/returns.c``) where it is built, else ``static_returns_numpy``: the same
bytes. A world with moving bodies maps its hits through ``World.surface_ids`` (see
``World.returns``)."""

import ctypes

import numpy as np

from ..native import kernels
from ..scene.geometry import pair_rows
from ..native.kernels import Kernel


def static_returns(dist, tri, table, rmin, rmax):
    """(valid, surface): per ray, whether it hit a triangle (``tri`` >= 0) at a range
    ``dist`` within [rmin, rmax]; and row ``tri`` of ``table`` ((T, 2) int32 object and
    material per triangle; a miss, -1, gets the last row, as numpy's take gives it)."""
    fn = STATIC_RETURNS.get() if compiled else None
    n = len(dist)
    if fn is None or len(table) == 0:
        return static_returns_numpy(dist, tri, table, rmin, rmax)
    keep = [np.ascontiguousarray(dist, np.float64), np.ascontiguousarray(tri, np.int64),
            np.ascontiguousarray(table, np.int32)]
    valid, surface = np.empty(n, np.bool_), np.empty((n, 2), np.int32)
    args = _ReturnsArgs(n, *(a.ctypes.data for a in keep), len(keep[2]), float(rmin),
                        float(rmax), valid.ctypes.data, surface.ctypes.data)
    if fn(ctypes.byref(args), kernels.threads()) < 0:
        raise IndexError("a hit triangle is outside the scene's table of surfaces")
    return valid, surface


def in_range(dist, tri, rmin, rmax):
    """Per ray, whether it hit a triangle (``tri`` >= 0) at a range within [rmin, rmax]."""
    return (tri >= 0) & (dist >= rmin) & (dist <= rmax)


def static_returns_numpy(dist, tri, table, rmin, rmax):
    """The reference of ``static_returns``."""
    valid = in_range(dist, tri, rmin, rmax)
    surface = pair_rows(table, tri) if len(table) else np.zeros((len(tri), 2), np.int32)
    return valid, surface


class _ReturnsArgs(ctypes.Structure):
    """``returns_t`` of native/c/returns.c."""

    _fields_ = [("n", ctypes.c_int64), ("dist", ctypes.c_void_p), ("tri", ctypes.c_void_p),
                ("table", ctypes.c_void_p), ("rows", ctypes.c_int64),
                ("rmin", ctypes.c_double), ("rmax", ctypes.c_double),
                ("valid", ctypes.c_void_p), ("surface", ctypes.c_void_p)]


NATIVE_RETURNS_ABI = 2
STATIC_RETURNS = Kernel("rls_static_returns", "rls_returns_abi", NATIVE_RETURNS_ABI,
                        [ctypes.POINTER(_ReturnsArgs), ctypes.c_int], ctypes.c_int64)
# Off: every frame works out its returns in numpy (the reference the C code is tested
# against).
compiled = True
