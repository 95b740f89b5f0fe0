"""A study's candidates: every mount (or grid position) at every pitch and yaw, each
with its sensor-to-world pose (``Candidate``); how the mounts and grid positions are
found and which way a candidate faces."""

import dataclasses
import math

import numpy as np

from ..errors import RegionError, SceneError
from ..metrics.polygon import as_polygon, polygon_centroid
from ..scene.mounting import facing_yaw_deg


@dataclasses.dataclass
class Candidate:
    index: int
    name: str
    mount: str
    position: tuple
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    pose: np.ndarray = None
    # filled by the scan
    n_points: int = 0
    infra_d: float = 0.0
    infra_nuc: float = float("nan")
    scan_points: int = 0
    rays: int = 0
    seconds: float = 0.0

    def row(self):
        return {"index": self.index, "name": self.name, "mount": self.mount,
                "x": round(self.position[0], 4), "y": round(self.position[1], 4),
                "z": round(self.position[2], 4), "yaw_deg": round(self.yaw_deg, 4),
                "pitch_deg": self.pitch_deg, "roll_deg": self.roll_deg,
                "points_in_lob": self.n_points, "infra_d": self.infra_d,
                "infra_nuc": self.infra_nuc if math.isfinite(self.infra_nuc) else None,
                "scan_points": self.scan_points, "rays": self.rays,
                "scan_seconds": round(self.seconds, 4)}


def make_candidates(spots, cfg, polygon):
    """Candidate placements: spots [(name, (x, y, z))] x pitches x yaws; with
    ``yaw_mode`` face, yaws from facing the centroid of the region's area."""
    centre = polygon_centroid(polygon)
    out = []
    for mount, pos in spots:
        base = facing_yaw_deg(pos, centre) if cfg.yaw_mode == "face" else 0.0
        for pitch in cfg.pitches:
            for yaw in cfg.yaws:
                y = base + yaw
                y = (y + 180.0) % 360.0 - 180.0
                name = f"{mount} pitch {pitch:g} yaw {yaw:+g}" if (
                    len(cfg.pitches) > 1 or len(cfg.yaws) > 1) else mount
                out.append(Candidate(len(out), name, mount, tuple(float(v) for v in pos), y,
                                     float(pitch), float(cfg.roll),
                                     pose_matrix(pos, y, pitch, cfg.roll)))
    _refuse_repeats(out)
    return out


def _refuse_repeats(candidates):
    """``RegionError`` when two candidates are one pose (a pitch or yaw given twice, a
    yaw and the same yaw 360 degrees on, a mount named twice): two LiDARs in one pose
    are no placement of two, and a set of them would count one sensor's points twice."""
    seen = {}
    for c in candidates:
        key = (np.round(np.asarray(c.pose, np.float64), 9) + 0.0).tobytes()  # -0.0 is 0.0
        other = seen.setdefault(key, c)
        if other is not c:
            raise RegionError(f"candidates '{other.name}' and '{c.name}' are the same pose "
                              f"(at {', '.join(f'{v:g}' for v in c.position)}, yaw {c.yaw_deg:g}, "
                              f"pitch {c.pitch_deg:g} degrees): give each pitch, yaw and mount "
                              "once (yaws 360 degrees apart are one yaw)")


# What a study keeps per candidate while it runs, beyond its disk counts (8 bytes a
# disk): the candidate itself (pose, name) and its spot, about 0.8 KiB measured with
# tracemalloc on a 10,201-point grid, rounded up.
CANDIDATE_BYTES = 1024


def grid_count(polygon, step, heights, margin=0.0):
    """How many positions ``grid_positions`` gives, without making them."""
    poly = as_polygon(polygon)
    if not (step > 0):
        raise RegionError(f"grid step must be positive, got {step}")
    span = poly.max(axis=0) - poly.min(axis=0) + 2 * margin
    per_axis = [int(math.floor((s + 1e-9) / step)) + 1 for s in span]
    return per_axis[0] * per_axis[1] * len(heights)


def study_bytes(candidates, disks):
    """The memory a study of ``candidates`` with ``disks`` disks holds (a lower bound:
    the scans themselves come on top, one candidate at a time)."""
    return int(candidates) * (int(disks) * 8 + CANDIDATE_BYTES)


def check_study_size(candidates, disks, available, step=None):
    """Refuse, before anything is made, a study whose candidates would not fit in the
    ``available`` memory (bytes; None: unknown, not checked)."""
    need = study_bytes(candidates, disks)
    if available is None or need <= available:
        return
    grid = f" (--grid {step:g})" if step else ""
    raise SceneError(f"the study has {candidates:,} candidates{grid} and needs about "
                     f"{need / 2**30:,.1f} GiB of memory for their counts ({disks} disks each), "
                     f"but {available / 2**30:,.1f} GiB are free: use a coarser --grid, fewer "
                     f"--heights, pitches or yaws, or fewer --disks")


def candidate_spots(scene, cfg, polygon, available=None):
    """[(name, (x, y, z))]: grid points (``cfg.grid_step``) and/or the scene's mounts,
    refused up front when their candidates would not fit in ``available`` bytes."""
    spots = []
    if cfg.grid_step:
        per_spot = len(cfg.pitches) * len(cfg.yaws)
        check_study_size(grid_count(polygon, cfg.grid_step, cfg.grid_heights,
                                    cfg.grid_margin) * per_spot,
                         cfg.disks, available, cfg.grid_step)
        for j, pos in enumerate(grid_positions(polygon, cfg.grid_step, cfg.grid_heights,
                                               cfg.grid_margin)):
            spots.append((f"grid{j:03d}@({pos[0]:g},{pos[1]:g},{pos[2]:g})", pos))
    if cfg.mounts or not cfg.grid_step:
        spots += scene.mounts(tuple(cfg.mounts))
    if not spots:
        raise SceneError(f"scene {scene.name!r} has no LiDAR mounts: mark pole objects with the "
                         "custom property rls_mount = True, name them with --mount, or use --grid")
    return spots


def grid_positions(polygon, step, heights, margin=0.0):
    """(x, y, z) candidate positions on a grid of ``step`` metres over the polygon's
    bounding box grown by ``margin``, at each height."""
    poly = as_polygon(polygon)
    if not (step > 0):
        raise RegionError(f"grid step must be positive, got {step}")
    lo, hi = poly.min(axis=0) - margin, poly.max(axis=0) + margin
    xs = np.arange(lo[0], hi[0] + 1e-9, step)
    ys = np.arange(lo[1], hi[1] + 1e-9, step)
    return [(float(x), float(y), float(z)) for z in heights for y in ys for x in xs]


def orientation_matrix(yaw_rad, pitch_down_rad, roll_rad=0.0):
    """3x3 rotation of a sensor with Blender XYZ Euler angles (roll, pitch, yaw), where
    a positive ``pitch_down`` tilts the sensor's +X axis below the horizon."""
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_down_rad), math.sin(pitch_down_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def pose_matrix(position, yaw_deg, pitch_down_deg, roll_deg=0.0):
    """4x4 sensor-to-world pose."""
    m = np.eye(4)
    m[:3, :3] = orientation_matrix(math.radians(yaw_deg), math.radians(pitch_down_deg),
                                   math.radians(roll_deg))
    m[:3, 3] = np.asarray(position, dtype=np.float64)
    return m
