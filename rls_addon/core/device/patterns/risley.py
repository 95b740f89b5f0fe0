"""Risley-prism scanners (Livox): beams refracted through 2 or 3 rotating wedge prisms.

Model (exact vector Snell refraction, no paraxial approximation), in a prism frame whose
optical axis is +z:

* prism i turns about the axis at ``rotation_hz[i]`` (sign = direction), angle
  ``theta_i(t) = 2*pi*f_i*t + phase_i``;
* every prism has one face perpendicular to the axis and one face tilted by its wedge
  angle ``|alpha_i|`` towards ``theta_i``; the sign of ``alpha_i`` says which face meets
  the beam first: positive = tilted face first, negative = flat face first (with this
  reading the HELIOS++ Livox parameters give the quoted full cones, 38.3 deg for the
  Mid-40 and 70.4 deg for the Mid-70);
* a beam refracts at both faces of each prism in turn (air -> glass -> air).

The rosette, its non-repetition and the growth of coverage with integration time follow
from the rotor frequencies; nothing is imposed. The prism frame maps to the sensor frame
as prism z -> +X (forward), prism x -> +Y (left), prism y -> +Z (up).
"""

import numpy as np

from ...errors import PatternError
from .base import ScanPattern

MAX_RAYS = 10_000_000


def refract(d, n, eta):
    """Vector Snell refraction of unit directions ``d`` (N,3) at a surface with unit
    normals ``n`` (N,3 or 3,), ``eta`` = n_incident / n_transmitted. The normal may point
    either way. Raises PatternError on total internal reflection."""
    n = np.broadcast_to(n, d.shape)
    cos_i = -np.einsum("ij,ij->i", d, n)
    flip = cos_i < 0  # make the normal face the incoming beam
    n = np.where(flip[:, None], -n, n)
    cos_i = np.abs(cos_i)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    if np.any(k < 0):
        raise PatternError("total internal reflection in the prism train: wedge angles or "
                           "refractive index too large for this beam")
    t = eta * d + (eta * cos_i - np.sqrt(k))[:, None] * n
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def tilted_normals(theta, alpha_rad):
    """Normals (N,3) of a face tilted by ``alpha`` towards azimuth ``theta`` (prism frame)."""
    sa = np.sin(alpha_rad)
    return np.stack([sa * np.cos(theta), sa * np.sin(theta),
                     np.full_like(theta, np.cos(alpha_rad))], axis=1)


def beam_fan(fan_deg):
    """Incident unit directions (B,3), prism frame, for beams tilted by ``fan_deg`` in the
    vertical (prism y) plane."""
    a = np.deg2rad(np.asarray(fan_deg, dtype=np.float64).reshape(-1))
    return np.stack([np.zeros_like(a), np.sin(a), np.cos(a)], axis=1)


def deflect(incident, times, rotation_hz, wedge_deg, refractive_index, phase_deg=None):
    """Directions (N,3), prism frame, of beams ``incident`` (N,3) leaving the prism train
    at ``times`` (N,)."""
    f = np.asarray(rotation_hz, dtype=np.float64)
    a = np.deg2rad(np.asarray(wedge_deg, dtype=np.float64))
    ph = np.zeros_like(f) if phase_deg is None else np.deg2rad(np.asarray(phase_deg, float))
    if f.shape != a.shape or f.shape != ph.shape or not 1 <= f.size <= 3:
        raise PatternError("a Risley scanner needs 1 to 3 prisms with one rotation rate, wedge "
                           "angle and phase each")
    nglass = float(refractive_index)
    if not 1.0 < nglass < 4.0:
        raise PatternError(f"refractive index must lie in (1, 4), got {nglass}")
    axis = np.array([0.0, 0.0, 1.0])
    d = np.array(incident, dtype=np.float64)
    for i in range(f.size):  # 1-3 prisms: the loop is over optical surfaces, not rays
        theta = 2.0 * np.pi * f[i] * times + ph[i]
        tilted = tilted_normals(theta, abs(a[i]))
        first, second = (tilted, axis) if a[i] > 0 else (axis, tilted)
        d = refract(d, first, 1.0 / nglass)
        d = refract(d, second, nglass)
    return d


def prism_to_sensor(d):
    """Prism frame (optical axis +z) to sensor frame (+X forward, +Y left, +Z up)."""
    return np.stack([d[:, 2], d[:, 0], d[:, 1]], axis=1)


def risley_pattern(frequency_hz, pulse_rate_hz, rotation_hz, wedge_deg, refractive_index,
                   fan_deg=(0.0,), phase_deg=None, frame=0, duration_s=None):
    """Rays of one frame (or of ``duration_s`` seconds) of a Risley scanner.

    pulse_rate_hz  firings per second of each beam; all beams of the fan fire together
    fan_deg        vertical tilt of each incident beam (one channel per entry)
    frame          frame index: the prisms keep turning, so frame k continues where
                   frame k-1 stopped (times in the result are since the frame start)
    """
    if not frequency_hz > 0 or not pulse_rate_hz > 0:
        raise PatternError("frequency_hz and pulse_rate_hz must be positive")
    period = 1.0 / frequency_hz
    span = period if duration_s is None else float(duration_s)
    shots = int(np.floor(span * pulse_rate_hz + 1e-9))
    fan = beam_fan(fan_deg)
    b = fan.shape[0]
    if shots < 1 or shots * b > MAX_RAYS:
        raise PatternError(f"{shots * b} rays per frame is outside 1..{MAX_RAYS}")
    t = np.arange(shots) / pulse_rate_hz
    t_abs = np.repeat(t + frame * period, b)
    inc = np.tile(fan, (shots, 1))
    d = deflect(inc, t_abs, rotation_hz, wedge_deg, refractive_index, phase_deg)
    ch = np.tile(np.arange(b, dtype=np.uint16), shots)
    return ScanPattern(prism_to_sensor(d), np.repeat(t, b), ch, max(period, span))


def cone_angle_deg(directions):
    """Full cone angle (degrees) about +X enclosing all ``directions``."""
    d = np.asarray(directions, dtype=np.float64)
    return 2.0 * np.degrees(np.max(np.arccos(np.clip(d[:, 0], -1.0, 1.0))))
