"""Synthetic point clouds for the file-format tests."""

import numpy as np

from rls_addon.core.points import empty_points


def sample_cloud(n, seed=0):
    rng = np.random.default_rng(seed)
    p = empty_points(n)
    for f in "xyz":
        p[f] = rng.uniform(-120.0, 120.0, n)
    p["range"] = np.sqrt(p["x"] ** 2 + p["y"] ** 2 + p["z"] ** 2)
    p["intensity"] = rng.random(n)
    p["ring"] = np.arange(n) % 64
    p["time"] = np.sort(rng.uniform(0.0, 0.1, n))
    p["label"] = np.repeat(rng.integers(0, 17, n // 50 + 1), 50)[:n]
    p["instance"] = rng.integers(0, 2**31, n, dtype=np.uint32)  # stable ids are 31-bit
    p["ghost"] = rng.random(n) < 0.05
    return p


def stored(points, field, time_dtype="float64"):
    """What a file holds for ``field``: x y z intensity range as float32, the rest exact."""
    col = points[field]
    if field in ("x", "y", "z", "intensity", "range"):
        return col.astype(np.float32)
    if field == "time" and time_dtype == "float32":
        return col.astype(np.float32)
    return col
