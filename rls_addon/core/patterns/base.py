"""The scan-pattern contract shared by every family."""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import PatternError


@dataclass(frozen=True)
class ScanPattern:
    """The rays of one frame, in firing order.

    directions  (N, 3) float64 unit vectors in the sensor frame (+X forward, +Y left, +Z up)
    times       (N,)   float64 seconds since the start of the frame, non-decreasing
    channels    (N,)   uint16 vendor channel / ring index
    period      float  frame period in seconds (times lie in [0, period))
    """

    directions: np.ndarray
    times: np.ndarray
    channels: np.ndarray
    period: float

    def __post_init__(self):
        d = self.directions
        if d.ndim != 2 or d.shape[1] != 3:
            raise PatternError(f"pattern directions must have shape (N, 3), got {d.shape}")
        n = d.shape[0]
        if self.times.shape != (n,) or self.channels.shape != (n,):
            raise PatternError("pattern times and channels must have one entry per direction")
        if not (self.period > 0):
            raise PatternError(f"pattern period must be positive, got {self.period}")

    def __len__(self):
        return self.directions.shape[0]

    @cached_property
    def columns(self):
        """The directions as a contiguous (3, N) array (x, y and z rows): gathering
        one coordinate of many rays then reads one contiguous row."""
        return np.ascontiguousarray(self.directions.T)


def directions_from_angles(azimuth_rad, elevation_rad):
    """Unit vectors for azimuth (from +X towards +Y, counter-clockwise seen from above)
    and elevation (up from the XY plane), both in radians. Returns (N, 3) float64."""
    az = np.asarray(azimuth_rad, dtype=np.float64)
    el = np.asarray(elevation_rad, dtype=np.float64)
    ce = np.cos(el)
    return np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=-1)


def angles_from_directions(directions):
    """Inverse of ``directions_from_angles``: (azimuth, elevation) in radians."""
    d = np.asarray(directions, dtype=np.float64)
    az = np.arctan2(d[:, 1], d[:, 0])
    el = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    return az, el
