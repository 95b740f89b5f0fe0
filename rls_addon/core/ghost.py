"""Ghost points from specular surfaces (glass, water, polished metal, traffic signs).

A beam that hits a mirror-like surface at distance a may travel on along the
reflected direction r = u - 2(u.n)n, hit a second object at distance b, and return
the same way; the sensor then reports a point at a + b along the original beam: the
mirror image of the second object. Which glossy hits become ghosts is decided per
material by a ghost ratio (default 0.5, as the paper) with the scan's generator.
"""

import numpy as np

from .labels import NAME_TO_ID

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
    return u - 2.0 * np.einsum("ij,ij->i", u, n)[:, None] * n


def bounce_origins(points, u, n, distance):
    """Start points for reflected rays: the hit point moved off the surface, towards the
    side the beam came from, by a scale-aware epsilon (a few float32 ulps of the
    distance travelled), so that a reflected ray never re-hits its own surface."""
    side = np.where(np.einsum("ij,ij->i", u, n)[:, None] < 0, n, -n)
    eps = 1e-6 + 4e-6 * np.asarray(distance)[:, None]
    return points + side * eps
