"""Spinning multi-beam LiDARs (Velodyne, Hesai, Ouster, RoboSense) and the uniform
CARLA-style parameterisation.

The head turns clockwise seen from above (as real devices do), so our azimuth
(counter-clockwise from +X) decreases with time; at t = 0 the head points at +X.
Every channel fires once per firing cycle; a channel's firing offset within the cycle
sets both its timestamp and the head azimuth it sees, so timestamps follow firing order.
"""

import numpy as np

from ...errors import PatternError
from .base import ScanPattern, directions_from_angles

MAX_RAYS = 10_000_000


def uniform_elevations_deg(channels, upper_fov_deg, lower_fov_deg):
    """CARLA-style evenly spaced elevations from upper to lower FOV (degrees)."""
    if channels < 1:
        raise PatternError(f"channels must be >= 1, got {channels}")
    if channels == 1:
        return np.array([float(upper_fov_deg)])
    return np.linspace(float(upper_fov_deg), float(lower_fov_deg), int(channels))


def firing_cycles(frequency_hz, channels, points_per_second=None, horizontal_resolution_deg=None,
                  firing_cycle_s=None, firings_per_rotation=None):
    """(cycles per revolution, cycle time in s) from exactly one rate parameter.

    points_per_second          cycles = round(pps / f / channels), spread evenly
    horizontal_resolution_deg  cycles = round(360 / resolution)
    firings_per_rotation       cycles = that number: firing locked to the motor (one
                               firing per azimuth step, PandarQT, XT-32), so the cycle is
                               1 / (f * cycles) at any rotation rate
    firing_cycle_s             the device's fixed cycle (e.g. VLP-16 55.296 us);
                               cycles = floor(period / cycle) so the last one ends in the frame
    """
    if not frequency_hz > 0:
        raise PatternError(f"frequency_hz must be positive, got {frequency_hz}")
    given = [v is not None for v in (points_per_second, horizontal_resolution_deg, firing_cycle_s,
                                     firings_per_rotation)]
    if sum(given) != 1:
        raise PatternError("give exactly one of points_per_second, horizontal_resolution_deg, "
                           "firing_cycle_s, firings_per_rotation")
    period = 1.0 / frequency_hz
    if points_per_second is not None:
        if not points_per_second > 0:
            raise PatternError(f"points_per_second must be positive, got {points_per_second}")
        n = int(round(points_per_second * period / channels))
    elif horizontal_resolution_deg is not None:
        if not 0 < horizontal_resolution_deg <= 360:
            raise PatternError(f"horizontal_resolution_deg must be in (0, 360], got "
                               f"{horizontal_resolution_deg}")
        n = int(round(360.0 / horizontal_resolution_deg))
    elif firings_per_rotation is not None:
        if int(firings_per_rotation) != firings_per_rotation:
            raise PatternError(f"firings_per_rotation must be a whole number, got "
                               f"{firings_per_rotation}")
        n = int(firings_per_rotation)
    else:
        if not 0 < firing_cycle_s <= period:
            raise PatternError(f"firing cycle {firing_cycle_s} s must be positive and within "
                               f"the frame period {period} s")
        n = int(np.floor(period / firing_cycle_s + 1e-9))
        return n, float(firing_cycle_s)
    if n < 1:
        raise PatternError("rate too low for one firing per revolution")
    return n, period / n


def spinning_pattern(elevations_deg, frequency_hz, points_per_second=None, azimuth_offsets_deg=None,
                     *, horizontal_resolution_deg=None, firing_cycle_s=None, firing_offsets_s=None,
                     origins_head_m=None, firings_per_rotation=None):
    """One revolution of a spinning multi-beam sensor.

    elevations_deg       (C,) per-channel elevation, table (firing) order
    azimuth_offsets_deg  (C,) per-channel azimuth offset in OUR convention (counter-clockwise
                         from the head direction); convert vendor tables with
                         ``angle_tables.ccw_offsets_deg`` first
    firing_offsets_s     (C,) per-channel firing time within the cycle (default: all channels
                         fire together at the start of the cycle); each must be < cycle time
    origins_head_m       (C, 3) or (1, 3) where each channel's beam leaves from, in metres, in
                         the head frame (turning with the head: +X the head's direction at
                         the firing, +Y left, +Z up); None: every beam from the sensor origin.
                         A ray's origin is this point turned by the head angle at its firing.

    Returns a ``ScanPattern`` in firing order; channels are 0-based table rows.
    """
    el = np.asarray(elevations_deg, dtype=np.float64).reshape(-1)
    c = el.shape[0]
    if c < 1:
        raise PatternError("a spinning pattern needs at least one channel")
    if points_per_second is None and horizontal_resolution_deg is None and firing_cycle_s is None \
            and firings_per_rotation is None:
        raise PatternError("give one of points_per_second, horizontal_resolution_deg, firing_cycle_s, "
                           "firings_per_rotation")
    steps, cycle = firing_cycles(frequency_hz, c, points_per_second, horizontal_resolution_deg,
                                 firing_cycle_s, firings_per_rotation)
    if steps * c > MAX_RAYS:
        raise PatternError(f"{steps * c} rays per frame exceeds the limit of {MAX_RAYS}")
    period = 1.0 / frequency_hz
    off = np.zeros(c) if azimuth_offsets_deg is None else np.asarray(azimuth_offsets_deg, float)
    fire = np.zeros(c) if firing_offsets_s is None else np.asarray(firing_offsets_s, float)
    if off.shape != (c,) or fire.shape != (c,):
        raise PatternError(f"azimuth and firing offsets need one value per channel ({c})")
    if np.any(fire < 0) or np.any(fire >= cycle):
        raise PatternError(f"firing offsets must lie in [0, {cycle * 1e6:.3f} us) (the cycle time)")
    order = np.argsort(fire, kind="stable")  # firing order within a cycle
    el, off, fire = el[order], off[order], fire[order]
    t = (np.arange(steps)[:, None] * cycle + fire[None, :]).reshape(-1)
    az = -2.0 * np.pi * frequency_hz * t + np.tile(np.deg2rad(off), steps)
    elev = np.tile(np.deg2rad(el), steps)
    ch = np.tile(order.astype(np.uint16), steps)
    origins = None
    if origins_head_m is not None:
        oh = np.asarray(origins_head_m, np.float64).reshape(-1, 3)
        if oh.shape[0] not in (1, c):
            raise PatternError(f"beam origins need one (x, y, z) or one per channel ({c})")
        oh = np.broadcast_to(oh, (c, 3))[order]
        head = -2.0 * np.pi * frequency_hz * t  # the head's azimuth at each firing
        ch_, sh_ = np.cos(head), np.sin(head)
        o = np.tile(oh, (steps, 1))
        origins = np.stack([ch_ * o[:, 0] - sh_ * o[:, 1], sh_ * o[:, 0] + ch_ * o[:, 1],
                            o[:, 2]], axis=-1)
    return ScanPattern(directions_from_angles(az, elev), t, ch, period, origins)
