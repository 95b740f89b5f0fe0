"""The point record every stage after ray casting passes around.

A point cloud is one numpy structured array of ``POINT_DTYPE``:

x, y, z     float64  metres, sensor frame (+X forward, +Y left, +Z up) unless stated
range       float64  metres along the ray (for ghosts: the total path a + b)
intensity   float32  0..1
ring        uint16   vendor channel index
time        float64  seconds since the start of the frame's sweep
label       uint32   semantic class id (see ``labels``)
instance    uint32   stable per-object id (0 = none)
ghost       uint8    1 for a ghost point from a specular bounce
return_index uint8   1-based rank by range of this echo among the detected echoes of
                     its pulse (1 for a pulse with one echo; see ``footprint``)
num_returns uint8    how many echoes the pulse's beam brought back (1 unless its
                     footprint straddled a depth edge)
"""

import numpy as np

POINT_DTYPE = np.dtype(
    [
        ("x", np.float64),
        ("y", np.float64),
        ("z", np.float64),
        ("range", np.float64),
        ("intensity", np.float32),
        ("ring", np.uint16),
        ("time", np.float64),
        ("label", np.uint32),
        ("instance", np.uint32),
        ("ghost", np.uint8),
        ("return_index", np.uint8),
        ("num_returns", np.uint8),
    ]
)


def point_dtype(fields=None):
    """``POINT_DTYPE`` with only ``fields`` (None: all), in its order; unknown names are
    refused."""
    if fields is None:
        return POINT_DTYPE
    unknown = set(fields) - set(POINT_DTYPE.names)
    if unknown:
        raise ValueError(f"unknown point fields {sorted(unknown)}; known: {POINT_DTYPE.names}")
    return np.dtype([(f, POINT_DTYPE[f]) for f in POINT_DTYPE.names if f in set(fields)])


def empty_points(n=0):
    """Return a zeroed point array of length ``n``."""
    return np.zeros(int(n), dtype=POINT_DTYPE)


def xyz(points):
    """(N, 3) float64 copy of the coordinates of ``points``."""
    return np.stack([points["x"], points["y"], points["z"]], axis=1)


def transform_points(points, matrix):
    """Return a copy of ``points`` with x, y, z mapped by the 4x4 ``matrix``."""
    out = points.copy()
    m = np.asarray(matrix, dtype=np.float64)
    p = xyz(points) @ m[:3, :3].T + m[:3, 3]
    out["x"], out["y"], out["z"] = p[:, 0], p[:, 1], p[:, 2]
    return out
