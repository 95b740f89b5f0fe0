"""MEMS mirror scanners: Lissajous zones (RoboSense M1-like) and a two-mirror
Blickfeld-style variant.

Both give (horizontal, vertical) scan angles in degrees, horizontal positive to the
RIGHT (as the vendors draw it) and vertical positive up; ``_to_pattern`` turns them into
sensor-frame unit vectors (our azimuth is counter-clockwise, so azimuth = -horizontal).
Rays per frame = point rate x frame time.
"""

import numpy as np

from ...errors import PatternError
from .base import ScanPattern, directions_from_angles

MAX_RAYS = 10_000_000

# The M1-like model of the PCSim RLS library (Solid_state.cpp), via the project reference.
M1_ZONES = (
    # (horizontal offset deg, rotation deg, upper centre c_u deg, lower centre c_l deg);
    # the rotations are 0.01*pi and 0.02*pi rad = 1.8 and 3.6 deg
    (0.0, 0.0, 3.25, 5.25),
    (-24.0, -1.8, 2.25, 6.25),
    (24.0, 1.8, 2.25, 6.25),
    (-48.0, -3.6, 0.25, 8.25),
    (48.0, 3.6, 0.25, 8.25),
)


def _frame_times(frequency_hz, points_per_second, beams, frame):
    if not frequency_hz > 0 or not points_per_second > 0:
        raise PatternError("frequency_hz and points_per_second must be positive")
    period = 1.0 / frequency_hz
    shots = int(round(points_per_second * period / beams))
    if shots < 1 or shots * beams > MAX_RAYS:
        raise PatternError(f"{shots * beams} rays per frame is outside 1..{MAX_RAYS}")
    t = np.arange(shots) * (period / shots)
    return t, t + frame * period, period


def _to_pattern(h_deg, v_deg, times, channels, period):
    d = directions_from_angles(np.deg2rad(-h_deg), np.deg2rad(v_deg))
    return ScanPattern(d, times, channels.astype(np.uint16), period)


def lissajous_zones_pattern(frequency_hz, points_per_second, zones=M1_ZONES,
                            h_mirror_hz=7200.0, v_mirror_hz=100.0, h_amplitude_deg=12.5,
                            upper_amplitude_deg=9.25, lower_amplitude_deg=7.25,
                            v_phase_deg=90.0, frame=0):
    """Zoned Lissajous MEMS pattern (RoboSense M1-like).

    For each zone (offset_deg, rotation_deg, c_u, c_l) and each band (upper, lower) one beam:
        x = A_h cos(2 pi f_h t)
        y_upper = A_u sin(2 pi f_v t + phase) + c_u;  y_lower = A_l sin(...) - c_l
    (x, y) is rotated by the zone's rotation about the zone centre, then x += offset.
    All 2 * len(zones) beams fire together; channel = 2 * zone + band (0 upper, 1 lower).
    """
    z = np.asarray(zones, dtype=np.float64).reshape(-1, 4)
    beams = 2 * z.shape[0]
    t, t_abs, period = _frame_times(frequency_hz, points_per_second, beams, frame)
    x = h_amplitude_deg * np.cos(2 * np.pi * h_mirror_hz * t_abs)
    s = np.sin(2 * np.pi * v_mirror_hz * t_abs + np.deg2rad(v_phase_deg))
    # (shots, zones, band) arrays
    y = np.stack([upper_amplitude_deg * s[:, None] + z[None, :, 2],
                  lower_amplitude_deg * s[:, None] - z[None, :, 3]], axis=2)
    xx = np.broadcast_to(x[:, None, None], y.shape)
    rot = np.deg2rad(z[None, :, 1, None])
    c, sn = np.cos(rot), np.sin(rot)
    h = xx * c - y * sn + z[None, :, 0, None]
    v = xx * sn + y * c
    ch = np.broadcast_to(np.arange(beams).reshape(1, -1, 2), y.shape)
    return _to_pattern(h.reshape(-1), v.reshape(-1), np.repeat(t, beams), ch.reshape(-1), period)


def blickfeld_pattern(frequency_hz, points_per_second, mirror_hz=150.0, h_fov_deg=70.0,
                      v_fov_deg=30.0, phase_deg=90.0, frame=0):
    """Two-mirror Blickfeld-style scan: both mirrors oscillate at the same frequency,
    the vertical amplitude ramps from zero to its full value over the frame, so the
    ellipse traced by the beam grows each frame (one beam, channel 0):
        x = (h_fov/2) sin(2 pi f t),  y = (v_fov/2) (t/T) sin(2 pi f t + phase)
    The ramp restarts every frame (t is the time since the frame start)."""
    t, t_abs, period = _frame_times(frequency_hz, points_per_second, 1, frame)
    w = 2 * np.pi * mirror_hz * t_abs
    h = 0.5 * h_fov_deg * np.sin(w)
    v = 0.5 * v_fov_deg * (t / period) * np.sin(w + np.deg2rad(phase_deg))
    return _to_pattern(h, v, t, np.zeros(t.shape[0], dtype=np.uint16), period)
