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


def points_to_world(points, info, where="the cloud"):
    """A copy of ``points`` in the world frame, as its sidecar ``info`` says they are:
    world-frame points as they are; sensor-frame points through ``sensor_to_world``, or
    for a sensor that moved during its sweep through its pose at each point's own time
    (the sidecar's ``sensor_poses`` knots). ``InputError`` naming ``where`` when the
    sidecar cannot say."""
    from .errors import InputError
    from .scene.motion import poses_at

    space = info.get("frame_space")
    if space is None and isinstance(info.get("frame"), str):
        space = info["frame"]
    if space in (None, "world"):
        return points
    if space != "sensor":
        raise InputError(f"sidecar of {where}: unknown coordinate frame {space!r} "
                         "(expected sensor or world)")
    knots = info.get("sensor_poses")
    out = points.copy()
    local = xyz(points)
    if knots:
        try:
            poses = poses_at(knots["times_s"], knots["matrices"], points["time"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"sidecar of {where}: unreadable sensor_poses ({exc})") from None
        w = np.einsum("nij,nj->ni", poses[:, :3, :3], local) + poses[:, :3, 3]
    else:
        m = info.get("sensor_to_world")
        m = np.asarray(m, dtype=np.float64) if m is not None else None
        if m is None or m.shape != (4, 4) or not np.isfinite(m).all():
            raise InputError(f"sidecar of {where} says the points are in the sensor frame but "
                             "has no valid 4x4 sensor_to_world")
        w = local @ m[:3, :3].T + m[:3, 3]
    out["x"], out["y"], out["z"] = w[:, 0], w[:, 1], w[:, 2]
    return out

