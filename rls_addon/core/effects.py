"""Sensor effects applied to hit records: range limits, noise, intensity, dropout.

Every function takes and returns plain arrays; randomness comes from the scan's
seeded ``numpy.random.Generator`` passed in by the caller.
"""

import zlib

import numpy as np


def scan_rng(seed, sensor, frame):
    """The generators of a scan, derived from (seed, sensor name, frame): one for range
    noise and dropout, one for the ghost choice. Separate streams keep a scan without
    glossy hits byte-identical whether ghosting is on or off."""
    key = zlib.crc32(str(sensor).encode("utf-8"))
    seq = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, key, int(frame) & 0xFFFFFFFF])
    return [np.random.default_rng(s) for s in seq.spawn(2)]


def incidence_cosine(directions, normals):
    """|cos| of the angle between each ray and the surface normal it hit."""
    return np.abs(np.einsum("ij,ij->i", directions, normals))


def intensity(reflectivity, cos_incidence, distance, attenuation_per_m=0.0):
    """Lambertian return: reflectivity * cos(incidence) * exp(-a * d), clipped to 0..1.

    With reflectivity 1 and cos 1 this is CARLA's distance-only intensity exp(-a*d)."""
    i = np.asarray(reflectivity) * np.asarray(cos_incidence)
    if attenuation_per_m:
        i = i * np.exp(-float(attenuation_per_m) * np.asarray(distance))
    return np.clip(i, 0.0, 1.0)


def range_noise(rng, n, sigma):
    """Gaussian range noise along the ray (zeros when sigma is 0; draws nothing then)."""
    if sigma <= 0:
        return np.zeros(n)
    return rng.standard_normal(n) * sigma  # the same draws as rng.normal(0, sigma, n)


def dropout_keep(rng, intensities, general_rate=0.0, intensity_limit=0.0, intensity_zero=0.0,
                 rays=None, n_rays=None):
    """CARLA's dropout: drop a random ``general_rate`` share of points; then a point with
    intensity I <= limit survives with probability (zero / limit) * I + (1 - zero).

    With ``rays`` (the ray index of each point) and ``n_rays``, the uniform draws are made
    per ray, so each ray's fate is independent of which other rays returned.
    """
    n = intensities.shape[0]
    rays = np.arange(n) if rays is None else rays
    n_rays = n if n_rays is None else n_rays
    keep = np.ones(n, dtype=bool)
    if general_rate > 0:
        keep &= rng.random(n_rays)[rays] >= general_rate
    if intensity_limit > 0 and intensity_zero > 0:
        p = (intensity_zero / intensity_limit) * intensities + (1.0 - intensity_zero)
        low = intensities <= intensity_limit
        keep &= ~low | (rng.random(n_rays)[rays] < p)
    return keep
