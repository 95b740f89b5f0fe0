"""The scan engine: one frame of one sensor, from triangles and a pattern to points.

Pure numpy around a ray-casting backend handed in by the caller (see ``raycast``).
"""

import time
from dataclasses import dataclass, field

import numpy as np

from . import effects
from .geometry import clean_for_casting
from .points import POINT_DTYPE
from .raycast import refine_hits


@dataclass(frozen=True)
class ScanSettings:
    """What a user chooses for a scan, beyond the device preset.

    Range and noise fields left as None take the preset's values."""

    seed: int = 0
    frame_space: str = "sensor"  # "sensor" or "world"
    noise: bool = True
    dropout: bool = True
    min_range_m: float | None = None
    max_range_m: float | None = None
    noise_sigma_m: float | None = None
    attenuation_per_m: float | None = None


@dataclass
class ScanResult:
    points: np.ndarray
    rays: int
    triangles: int
    seconds: float
    warnings: list = field(default_factory=list)


def sensor_axes(sensor_to_world):
    """Origin and orthonormal rotation of a 4x4 pose (scale and shear are removed)."""
    m = np.asarray(sensor_to_world, dtype=np.float64)
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:  # a mirrored sensor still looks along its own axes
        u[:, -1] *= -1
        r = u @ vt
    return m[:3, 3].copy(), r


def scan_frame(geometry, pattern, sensor_to_world, preset, settings, caster_factory,
               frame=0, sensor="sensor"):
    """Scan one frame.

    geometry         SceneGeometry in world coordinates
    pattern          ScanPattern (directions in the sensor frame)
    sensor_to_world  4x4 pose of the sensor
    preset           DevicePreset (range, dropout, attenuation)
    caster_factory   callable(vertices, triangles) -> caster (see ``raycast``)
    Returns a ScanResult whose points follow ``POINT_DTYPE``.
    """
    t0 = time.perf_counter()
    s = settings
    rmin = preset.range.min_m if s.min_range_m is None else s.min_range_m
    rmax = preset.range.max_m if s.max_range_m is None else s.max_range_m
    sigma = preset.range.noise_sigma_m if s.noise_sigma_m is None else s.noise_sigma_m
    atten = preset.attenuation_per_m if s.attenuation_per_m is None else s.attenuation_per_m
    rng = effects.scan_rng(s.seed, sensor, frame)

    origin, rot = sensor_axes(sensor_to_world)
    dirs_sensor = pattern.directions
    dirs = dirs_sensor @ rot.T
    local, tris, kept, warnings = clean_for_casting(geometry, origin, rmax)
    n = len(pattern)
    if geometry.triangle_count == 0:
        warnings.append("the scene has no geometry to scan")
    elif len(tris) == 0:
        warnings.append(f"no geometry within {rmax:g} m of the sensor")

    zero = np.zeros((1, 3))
    if len(tris):
        caster = caster_factory(local, tris)
        dist, tri = caster.cast(zero, dirs, rmax)
        dist, normals = refine_hits(local, tris, zero, dirs, dist, tri)
    else:
        dist, tri, normals = np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))

    hit = (tri >= 0) & (dist >= rmin) & (dist <= rmax)
    idx = np.nonzero(hit)[0]
    d = dist[idx]
    gtri = kept[tri[idx]] if len(idx) else np.zeros(0, np.int64)
    refl = np.array([m.reflectivity for m in geometry.materials], dtype=np.float64)
    cosi = effects.incidence_cosine(dirs[idx], normals[idx])
    inten = effects.intensity(refl[geometry.tri_material[gtri]] if len(idx) else np.zeros(0),
                              cosi, d, atten)
    if s.noise:
        d = d + effects.range_noise(rng, len(idx), sigma)
    keep = effects.dropout_keep(rng, inten, preset.dropout.general_rate,
                                preset.dropout.intensity_limit,
                                preset.dropout.intensity_zero) if s.dropout else np.ones(len(idx), bool)
    keep &= d > 0
    idx, d, gtri, inten = idx[keep], d[keep], gtri[keep], inten[keep]

    pts = np.zeros(len(idx), dtype=POINT_DTYPE)
    if s.frame_space == "world":
        xyz = origin + dirs[idx] * d[:, None]
    else:
        xyz = dirs_sensor[idx] * d[:, None]
    pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    pts["range"] = d
    pts["intensity"] = inten
    pts["ring"] = pattern.channels[idx]
    pts["time"] = pattern.times[idx]
    obj = geometry.tri_object[gtri]
    if len(geometry.objects):
        labels = np.array([o.label for o in geometry.objects], dtype=np.uint32)
        inst = np.array([o.instance for o in geometry.objects], dtype=np.uint32)
        pts["label"], pts["instance"] = labels[obj], inst[obj]
    return ScanResult(pts, n, len(tris), time.perf_counter() - t0, warnings)
