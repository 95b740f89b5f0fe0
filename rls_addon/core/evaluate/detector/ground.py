"""The ground under the scene, from background returns (world frame): what the roadside
detector measures an object's height from, and where it cuts foreground that is too
high (a bird, a false return from fog) or below the road."""

import numpy as np


class GroundGrid:
    """The ground's height under the scene from background returns (world frame): the
    lowest return in each ``cell`` m square, then the lowest within ``reach`` m (a square
    window), so a cell covered by a car, a roof or a wall reads the road next to it.
    ``at(xy)`` is NaN where nothing was seen within reach; ``height_at`` fills those
    with ``default`` (else the median of what was seen, else 0)."""

    def __init__(self, xyz, cell=1.0, reach=3.0, default=None):
        xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
        xyz = xyz[np.isfinite(xyz).all(axis=1)]
        self.cell = float(cell)
        if not len(xyz):
            self.origin, self.z = np.zeros(2), np.full((1, 1), np.nan)
        else:
            self.origin = np.floor(xyz[:, :2].min(0) / self.cell) * self.cell
            ij = np.floor((xyz[:, :2] - self.origin) / self.cell).astype(np.int64)
            shape = tuple(ij.max(0) + 1)
            z = np.full(shape, np.inf)
            np.minimum.at(z, (ij[:, 0], ij[:, 1]), xyz[:, 2])
            k = int(round(reach / self.cell))
            if k > 0:
                from scipy.ndimage import minimum_filter

                z = minimum_filter(z, size=2 * k + 1, mode="constant", cval=np.inf)
            self.z = np.where(np.isfinite(z), z, np.nan)
        if default is None:
            seen = self.z[np.isfinite(self.z)]
            default = float(np.median(seen)) if len(seen) else 0.0
        self.default = float(default)

    def at(self, xy):
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        ij = np.floor((xy - self.origin) / self.cell).astype(np.int64)
        ok = (ij >= 0).all(axis=1) & (ij[:, 0] < self.z.shape[0]) & (ij[:, 1] < self.z.shape[1])
        out = np.full(len(xy), np.nan)
        out[ok] = self.z[ij[ok, 0], ij[ok, 1]]
        return out

    def height_at(self, xy):
        """(N,) the ground's z under ``xy``, ``default`` where nothing was seen."""
        z = self.at(xy)
        return np.where(np.isnan(z), self.default, z)
