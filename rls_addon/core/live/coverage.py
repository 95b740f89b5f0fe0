"""The region's coverage over the LiDARs' latest clouds (``Coverage``): InfraD,
InfraNUC and the density map, kept per LiDAR so that rescanning one LiDAR costs only
its own cloud. Points per disk add up over clouds (as in the placement study:
``study.placement.DiskLayout``, the seeded disks placed once), so the numbers are
``infra_lob_metrics``' on all clouds together, without counting the others again.
``cells`` gives the map's cells and colours for a grid in the viewport."""

import dataclasses

import numpy as np

from ..metrics.infra import (DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED,
                             DensityMap, density_map, resolve_labels)
from ..study.placement import DiskLayout, set_metrics


@dataclasses.dataclass
class CoverageState:
    infra_d: float          # points per m² (0 without points)
    infra_nuc: float        # NaN without points in any disk (no estimate)
    n_points: int           # points counted in the region
    area_m2: float
    density: DensityMap
    sensors: tuple          # the LiDARs whose clouds are counted


class Coverage:
    """Coverage of the region ``polygon`` with the metric settings of ``rls metrics``."""

    def __init__(self, polygon, labels="road,sidewalk", disks=DEFAULT_DISKS,
                 radius=DEFAULT_RADIUS_M, seed=DEFAULT_SEED, disk_placement="inside",
                 cell=DEFAULT_CELL_M):
        self.layout = DiskLayout.make(polygon, disks, radius, seed, disk_placement)
        self.layout.prepare()
        self.polygon, self.cell = self.layout.polygon, float(cell)
        self.label_ids = resolve_labels(labels)
        self._xy, self._counts = {}, {}

    def set_cloud(self, key, points):
        """LiDAR ``key``'s latest cloud (world frame; x, y and label are read)."""
        xy = self.layout.select([points], self.label_ids)
        self._xy[key], self._counts[key] = xy, self.layout.counts(xy)

    def remove(self, key):
        self._xy.pop(key, None)
        self._counts.pop(key, None)

    def state(self):
        """The ``CoverageState`` of every cloud set."""
        keys = tuple(sorted(self._xy))
        n = sum(len(self._xy[k]) for k in keys)
        counts = (np.sum([self._counts[k] for k in keys], axis=0) if keys
                  else np.zeros(len(self.layout.centres), np.int64))
        d, u = set_metrics(np.array([n]), counts[None, :], self.layout.area_m2, self.layout.p)
        xy = np.concatenate([self._xy[k] for k in keys]) if keys else np.empty((0, 2))
        return CoverageState(float(d[0]), float(u[0]), int(n), self.layout.area_m2,
                             density_map(xy, self.polygon, self.cell), keys)


def cells(dm, vmax=None):
    """The map's cells inside the region: ((M, 2, 2) x/y corners (lower left, upper
    right) in world metres, (M, 4) RGBA in 0..1 as the density chart colours them:
    viridis from 0 to ``vmax`` (default: the densest cell), no return white)."""
    ny, nx = dm.values.shape
    inside = np.isfinite(dm.values)
    iy, ix = np.nonzero(inside)
    x0, y0 = dm.origin_xy
    lo = np.stack([x0 + ix * dm.cell_m, y0 + iy * dm.cell_m], axis=1)
    corners = np.stack([lo, lo + dm.cell_m], axis=1)
    rgba = dm.colours(vmax)[inside].astype(np.float64) / 255.0
    return corners, rgba


MAP_LEVELS = 16  # colour bands of the map in Solid shading (one material each)


def levels(dm, n=MAP_LEVELS, vmax=None):
    """The band of each of ``cells``' cells, in the same order: 0 for no return, else
    1..``n`` (density from 0 to ``vmax``, default the densest cell, in ``n`` equal
    bands; the densest in band ``n``). What a viewport shows through one material per
    band where it cannot show the cells' own colours (Solid shading)."""
    inside = np.isfinite(dm.values)
    v = dm.values[inside]
    if vmax is None:
        vmax = float(v.max()) if v.size else 0.0
    band = np.ones(v.shape, np.int32) if vmax <= 0 else \
        1 + np.minimum(np.floor(v / vmax * n), n - 1).astype(np.int32)
    band[v == 0] = 0
    return band


def level_colours(n=MAP_LEVELS):
    """(n + 1, 4) RGBA in 0..1 (sRGB) of ``levels``' bands: white for no return, then
    the density chart's viridis at each band's middle."""
    from ..output.png import colormap

    mids = (np.arange(n) + 0.5) / n
    out = np.ones((n + 1, 4))
    out[1:] = colormap(mids, vmin=0.0, vmax=1.0).astype(np.float64) / 255.0
    return out
