"""A small analytic spinning LiDAR for the detector's tests: 128 rings (-25 to +2 degrees,
about a Pandar64's density in its fine band) x 0.25 degree steps over the half turn in
front (+-90 degrees), cast against a ground disc and oriented boxes (cars, walls, poles),
seeded range noise, and
optional ghost flips (a glossy box whose returns are reported ``ghost_extra`` m farther
with probability 0.5, drawn per ray and frame, as RLS's ghosts are)."""

from dataclasses import dataclass

import numpy as np

from rls_addon.core.points import empty_points

ELEVATIONS_DEG = np.linspace(-25.0, 2.0, 128)
AZIMUTH_STEP_DEG = 0.25


@dataclass
class Solid:
    """An oriented box: centre x, y (m), bottom and top z, length along yaw, width."""
    x: float
    y: float
    length: float
    width: float
    yaw: float = 0.0
    z0: float = 0.0
    z1: float = 1.5
    glossy: bool = False

    @property
    def box(self):
        """(7,) as ``Boxes`` rows: x y z(centre) length width height yaw."""
        return np.array([self.x, self.y, (self.z0 + self.z1) / 2, self.length, self.width,
                         self.z1 - self.z0, self.yaw])


def car(x, y, yaw=0.0, length=4.5, width=1.8, height=1.5):
    return Solid(x, y, length, width, yaw, 0.3, 0.3 + height)


def pose(x=0.0, y=0.0, z=6.0, yaw=0.0, pitch=0.0):
    """4x4 sensor -> world: at (x, y, z), turned by yaw, looking down by pitch (radians)."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry
    m[:3, 3] = (x, y, z)
    return m


def directions(elevations_deg=None):
    """(R, 3) unit ray directions (sensor frame) and (R,) ring of the pattern."""
    el = np.radians(ELEVATIONS_DEG if elevations_deg is None else elevations_deg)
    az = np.radians(np.arange(-90.0, 90.0, AZIMUTH_STEP_DEG))
    E, A = np.meshgrid(el, az, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    ring = np.repeat(np.arange(len(el)), len(az))
    return d, ring


def scan(sensor_pose, solids=(), seed=0, sigma=0.02, ground_radius=60.0, max_range=100.0,
         ghost_extra=5.0, flip=None, elevations_deg=None):
    """One frame's points (RLS point records, sensor frame) of the scene. ``flip``: every
    glossy return a ghost (True), none (False), or each with probability 0.5 (None)."""
    rng = np.random.default_rng(seed)
    d, ring = directions(elevations_deg)
    R, t = sensor_pose[:3, :3], sensor_pose[:3, 3]
    dw = d @ R.T
    best = np.full(len(d), np.inf)
    glossy = np.zeros(len(d), bool)
    down = dw[:, 2] < 0
    tg = np.full(len(d), np.inf)
    tg[down] = -t[2] / dw[down, 2]
    hit = t[:2] + np.where(down, tg, 0.0)[:, None] * dw[:, :2]
    tg = np.where(np.hypot(hit[:, 0], hit[:, 1]) <= ground_radius, tg, np.inf)
    best = np.minimum(best, tg)
    for s in solids:
        c, si = np.cos(s.yaw), np.sin(s.yaw)
        rot = np.array([[c, -si, 0], [si, c, 0], [0, 0, 1]])
        o = (t - (s.x, s.y, (s.z0 + s.z1) / 2)) @ rot
        dl = dw @ rot
        half = np.array([s.length, s.width, s.z1 - s.z0]) / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half - o) / dl
            t2 = (half - o) / dl
        t1 = np.where(np.isnan(t1), -np.inf, t1)
        t2 = np.where(np.isnan(t2), np.inf, t2)
        tin = np.minimum(t1, t2).max(axis=1)
        tout = np.maximum(t1, t2).min(axis=1)
        ok = (tin <= tout) & (tin > 0)
        tb = np.where(ok, tin, np.inf)
        nearer = tb < best
        best = np.where(nearer, tb, best)
        glossy = np.where(nearer, s.glossy, glossy)
    keep = np.isfinite(best) & (best <= max_range)
    r = best + rng.normal(0.0, sigma, len(best))
    draw = rng.random(len(best)) < 0.5 if flip is None else np.full(len(best), bool(flip))
    r = np.where(glossy & draw, r + ghost_extra, r)
    pts = empty_points(int(keep.sum()))
    p = d[keep] * r[keep, None]
    pts["x"], pts["y"], pts["z"] = p[:, 0], p[:, 1], p[:, 2]
    pts["range"] = r[keep]
    pts["ring"] = ring[keep]
    pts["intensity"] = 0.5
    return pts


def frames(sensor_pose, solids=(), n=5, seed=100, **kw):
    return [scan(sensor_pose, solids, seed=seed + k, **kw) for k in range(n)]
