"""The scan engine: one frame of one sensor, from triangles and a pattern to points.

Pure numpy around a ray-casting backend handed in by the caller (see ``raycast``).
Static geometry is prepared once (``PreparedScene``: centred, culled, caster built)
and reused for every frame and sensor it covers.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from . import effects
from .geometry import clean_for_casting
from .points import POINT_DTYPE
from .raycast import WatertightCaster, refine_hits


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
    # Motion distortion: "exact" (every ray at its own time), "substeps" (the paper's
    # N partial sweeps) or "snapshot" (one scene state per frame, as CARLA).
    motion: str = "exact"
    substeps: int = 0  # 0: chosen adaptively for deforming objects; N: fixed
    motion_tolerance_m: float | None = None  # adaptive sub-step tolerance (None: preset)
    ghosting: bool = True  # ghost points from glossy surfaces


MOTION_MODES = ("exact", "substeps", "snapshot")


@dataclass
class ScanResult:
    points: np.ndarray
    rays: int
    triangles: int
    seconds: float
    warnings: list = field(default_factory=list)


class PreparedScene:
    """Triangles ready for casting around ``centre``: shifted to centre-relative float64
    coordinates (so scenes far from the origin keep their precision in float32
    backends), degenerate triangles dropped, everything farther than ``reach`` from
    ``centre`` culled, and the caster built once (wrapped so that rays through shared
    edges and vertices never slip through, see ``WatertightCaster``)."""

    def __init__(self, geometry, centre, reach, caster_factory, watertight=True):
        self.geometry = geometry
        self.centre = np.asarray(centre, dtype=np.float64).copy()
        self.reach = float(reach)
        self.vertices, self.triangles, self.kept, self.warnings = clean_for_casting(
            geometry, self.centre, self.reach)
        self.caster = None
        if len(self.triangles) and watertight:
            self.caster = WatertightCaster(caster_factory, self.vertices, self.triangles,
                                           geometry.tri_object[self.kept])
        elif len(self.triangles):
            self.caster = caster_factory(self.vertices, self.triangles)
        self.backend = getattr(self.caster, "name", "none")

    def covers(self, origin, max_range):
        """True when every ray of a sensor at ``origin`` stays inside the culled region."""
        gap = np.linalg.norm(np.asarray(origin, np.float64) - self.centre)
        return gap + max_range <= self.reach * (1 + 1e-12)

    def cast(self, origin, directions, max_range):
        """(dist, triangle index into the prepared triangles, unit normals) per ray."""
        n = directions.shape[0]
        if self.caster is None:
            return np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))
        o = (np.asarray(origin, np.float64) - self.centre).reshape(1, 3)
        dist, tri = self.caster.cast(o, directions, max_range)
        dist, normals = refine_hits(self.vertices, self.triangles, o, directions, dist, tri)
        return dist, tri, normals


def sensor_axes(sensor_to_world):
    """Origin and orthonormal rotation of a 4x4 pose (scale and shear are removed)."""
    m = np.asarray(sensor_to_world, dtype=np.float64)
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:  # a mirrored sensor still looks along its own axes
        u[:, -1] *= -1
        r = u @ vt
    return m[:3, 3].copy(), r


def resolve_range(preset, settings):
    """(min, max) range in metres after the settings' overrides."""
    rmin = preset.range.min_m if settings.min_range_m is None else settings.min_range_m
    rmax = preset.range.max_m if settings.max_range_m is None else settings.max_range_m
    return rmin, rmax


def scan_frame(scene, pattern, sensor_to_world, preset, settings, caster_factory=None,
               frame=0, sensor="sensor"):
    """Scan one frame.

    scene            PreparedScene covering the sensor, or a SceneGeometry (world
                     coordinates), prepared here around the sensor with caster_factory
    pattern          ScanPattern (directions in the sensor frame)
    sensor_to_world  4x4 pose of the sensor
    preset           DevicePreset (range, dropout, attenuation)
    Returns a ScanResult whose points follow ``POINT_DTYPE``.
    """
    t0 = time.perf_counter()
    s = settings
    rmin, rmax = resolve_range(preset, s)
    sigma = preset.range.noise_sigma_m if s.noise_sigma_m is None else s.noise_sigma_m
    atten = preset.attenuation_per_m if s.attenuation_per_m is None else s.attenuation_per_m
    rng = effects.scan_rng(s.seed, sensor, frame)

    origin, rot = sensor_axes(sensor_to_world)
    if not isinstance(scene, PreparedScene):
        scene = PreparedScene(scene, origin, rmax, caster_factory)
    elif not scene.covers(origin, rmax):
        raise ValueError("the prepared scene does not cover this sensor's range")
    geometry = scene.geometry
    warnings = list(scene.warnings)
    if geometry.triangle_count == 0:
        warnings.append("the scene has no geometry to scan")
    elif len(scene.triangles) == 0:
        warnings.append(f"no geometry within {rmax:g} m of the sensor")

    dirs_sensor = pattern.directions
    dirs = dirs_sensor @ rot.T
    dist, tri, normals = scene.cast(origin, dirs, rmax)

    hit = (tri >= 0) & (dist >= rmin) & (dist <= rmax)
    idx = np.nonzero(hit)[0]
    d = dist[idx]
    gtri = scene.kept[tri[idx]]
    refl = np.array([m.reflectivity for m in geometry.materials], dtype=np.float64)
    cosi = effects.incidence_cosine(dirs[idx], normals[idx])
    inten = effects.intensity(refl[geometry.tri_material[gtri]], cosi, d, atten)
    if s.noise:
        d = d + effects.range_noise(rng, len(idx), sigma)
    if s.dropout:
        keep = effects.dropout_keep(rng, inten, preset.dropout.general_rate,
                                    preset.dropout.intensity_limit, preset.dropout.intensity_zero)
    else:
        keep = np.ones(len(idx), bool)
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
    if geometry.objects:
        obj = geometry.tri_object[gtri]
        labels = np.array([o.label for o in geometry.objects], dtype=np.uint32)
        inst = np.array([o.instance for o in geometry.objects], dtype=np.uint32)
        pts["label"], pts["instance"] = labels[obj], inst[obj]
    return ScanResult(pts, len(pattern), len(scene.triangles), time.perf_counter() - t0, warnings)
