"""What imported people and bicycles stand on: the scene's ground surfaces under them.

SUMO's network is flat (or has its own z), while a scene has raised sidewalks (0.15 m
kerbs from ``rls scene from-net``, the sample scenes' kerbs) and maybe terrain. A
pedestrian or cyclist keyed at FCD's z would stand inside the sidewalk, so its box
bottom is put on the highest ground surface under its box centre that lies within
``STEP_M`` of FCD's z (above or below): a ray cast straight down from ``STEP_M`` above
FCD's z, ``2 * STEP_M`` long, through the scene's surfaces labelled ``GROUND_LABELS``.
Where no surface is that near (off the modelled ground, or a scene far from the
network's heights), FCD's z is kept. Vehicles keep FCD's z: they drive on the roads,
which are at the network's height.
"""

import numpy as np

GROUND_LABELS = ("road", "sidewalk", "terrain", "ground")
STANDING_LABELS = ("pedestrian", "cyclist")
STEP_M = 0.5   # kerbs are 0.1-0.2 m; a surface 0.5 m from FCD's z is another level


class GroundSurface:
    """The ground triangles of a scene, cast down through with a ``Caster`` class."""

    def __init__(self, vertices, triangles, caster_cls):
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        self.caster = caster_cls(np.asarray(vertices, dtype=np.float64),
                                 self.triangles) if len(self.triangles) else None

    def heights(self, xy, z):
        """(N,) heights to stand at for (N, 2) ``xy`` whose FCD height is (N,) ``z``:
        the first surface down from ``z + STEP_M`` within ``2 * STEP_M``, else ``z``."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        z = np.broadcast_to(np.asarray(z, dtype=np.float64), (len(xy),)).copy()
        if self.caster is None or not len(xy):
            return z
        top = z + STEP_M
        origins = np.column_stack([xy, top])
        down = np.broadcast_to(np.array([0.0, 0.0, -1.0]), origins.shape)
        dist, tri = self.caster.cast(origins, np.ascontiguousarray(down), 2.0 * STEP_M)
        hit = (tri >= 0) & np.isfinite(dist)
        z[hit] = top[hit] - dist[hit]
        return z
