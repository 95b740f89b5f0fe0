"""Spinning multi-beam LiDARs (Velodyne, Hesai, Ouster, RoboSense)."""

import numpy as np

from ..errors import PatternError
from .base import ScanPattern, directions_from_angles


def uniform_elevations_deg(channels, upper_fov_deg, lower_fov_deg):
    """CARLA-style evenly spaced elevations from upper to lower FOV (degrees)."""
    if channels < 1:
        raise PatternError(f"channels must be >= 1, got {channels}")
    if channels == 1:
        return np.array([float(upper_fov_deg)])
    return np.linspace(float(upper_fov_deg), float(lower_fov_deg), int(channels))


def spinning_pattern(elevations_deg, frequency_hz, points_per_second, azimuth_offsets_deg=None):
    """One revolution of a spinning multi-beam sensor.

    All channels fire together once per azimuth step (a simplification refined by the
    pattern work); the head turns clockwise seen from above, starting at azimuth 0 (+X).
    Returns a ``ScanPattern`` with channels numbered 0..C-1 in table order.
    """
    el = np.asarray(elevations_deg, dtype=np.float64)
    c = el.shape[0]
    if frequency_hz <= 0 or points_per_second <= 0:
        raise PatternError("frequency_hz and points_per_second must be positive")
    period = 1.0 / frequency_hz
    steps = int(round(points_per_second * period / c))
    if steps < 1:
        raise PatternError("points_per_second too low for one firing per revolution")
    off = np.zeros(c) if azimuth_offsets_deg is None else np.asarray(azimuth_offsets_deg, float)
    step_t = period / steps
    t = np.repeat(np.arange(steps) * step_t, c)
    az = -2.0 * np.pi * frequency_hz * t + np.deg2rad(np.tile(off, steps))
    elev = np.deg2rad(np.tile(el, steps))
    ch = np.tile(np.arange(c, dtype=np.uint16), steps)
    return ScanPattern(directions_from_angles(az, elev), t, ch, period)
