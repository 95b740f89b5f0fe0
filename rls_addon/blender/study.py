"""Placement study in a Blender scene: scan every candidate placement of one device
over the static scene once, measure InfraD / InfraNUC in the InfraLOB, and search
sets of k sensors (``core.study``).

As in the paper, traffic is removed before the metrics are taken: objects labelled
vehicle or pedestrian are left out of the geometry (the scene itself is not
changed). The static geometry is read once and one ray-casting structure, built by
one ``ScanSession`` around the region's centre with a reach that covers every
candidate, serves all candidates.
"""

import dataclasses
import math
import time

import bpy
import numpy as np

from ..core.engine import ScanSettings, resolve_range, scan_frame
from ..core.errors import RegionError, SceneError
from ..core.labels import label_id
from ..core.metrics import (DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED,
                            density_map, resolve_labels)
from ..core.presets import get_preset
from ..core.study import (DEFAULT_EXHAUSTIVE_LIMIT, CandidateCounts, DiskLayout, facing_yaw_deg,
                          grid_positions, pose_matrix)
from .backends import caster_factory
from .extract import object_table, read_instances, world_geometry
from .region import is_lob, lob_polygon_world
from .scan import ScanSession
from .scenes.build import is_mount, mount_position

TRAFFIC_LABELS = ("vehicle", "pedestrian")


@dataclasses.dataclass
class StudyConfig:
    device: str = "generic_uniform32"
    k: tuple = (1,)
    lob: str = None                 # region object name (default: the one marked object)
    mounts: tuple = ()              # mount object names (default: every marked mount)
    grid_step: float = None         # grid of positions instead of (or besides) mounts
    grid_heights: tuple = (6.0,)
    grid_margin: float = 0.0
    pitches: tuple = (0.0,)         # degrees, positive tilts the sensor's +X down
    yaws: tuple = (0.0,)            # degrees
    yaw_mode: str = "face"          # "face": yaw relative to facing the region centre
    roll: float = 0.0
    labels: str = "road,sidewalk"
    disks: int = DEFAULT_DISKS
    radius: float = DEFAULT_RADIUS_M
    disk_seed: int = DEFAULT_SEED
    disk_placement: str = "inside"
    cell: float = DEFAULT_CELL_M
    scan_seed: int = 0
    noise: bool = True
    dropout: bool = True
    ghosting: bool = True
    keep_traffic: bool = False
    backend: str = "auto"
    frame: int = None
    one_per_mount: bool = True
    exhaustive_limit: int = DEFAULT_EXHAUSTIVE_LIMIT


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


@dataclasses.dataclass
class StudyResult:
    config: StudyConfig
    scene: str
    frame: int
    device: dict
    polygon: np.ndarray
    layout: DiskLayout
    candidates: list
    counts: CandidateCounts
    searches: dict                  # k -> core.study.SearchResult
    xy: list                        # per candidate (N, 2) kept points
    timing: dict
    hidden_traffic: list
    backend: str
    structure_builds: int
    notices: list

    def density(self, members):
        xy = np.concatenate([self.xy[i] for i in members]) if members else np.empty((0, 2))
        return density_map(xy, self.polygon, self.config.cell)


def find_lob(scene, name=None):
    """The InfraLOB object: ``name``, else the single object marked ``rls_infralob``."""
    if name:
        obj = scene.objects.get(name)
        if obj is None:
            raise RegionError(f"no object named {name!r} in scene {scene.name!r}")
        return obj
    marked = sorted((o for o in scene.objects if is_lob(o)), key=lambda o: o.name)
    if not marked:
        raise RegionError(f"scene {scene.name!r} has no InfraLOB: mark a flat mesh with the "
                          "custom property rls_infralob = True, or pass --lob NAME")
    if len(marked) > 1:
        raise RegionError("several InfraLOB objects (" + ", ".join(o.name for o in marked)
                          + "); choose one with --lob NAME")
    return marked[0]


def find_mounts(scene, names=()):
    if names:
        out = []
        for n in names:
            obj = scene.objects.get(n)
            if obj is None:
                raise SceneError(f"no mount object named {n!r} in scene {scene.name!r}")
            out.append(obj)
        return out
    return sorted((o for o in scene.objects if is_mount(o)), key=lambda o: o.name)


def make_candidates(scene, cfg, polygon):
    """Candidate placements: mounts (or grid points) x pitches x yaws."""
    centre = polygon.mean(axis=0)
    spots = []
    if cfg.grid_step:
        for j, pos in enumerate(grid_positions(polygon, cfg.grid_step, cfg.grid_heights,
                                               cfg.grid_margin)):
            spots.append((f"grid{j:03d}@({pos[0]:g},{pos[1]:g},{pos[2]:g})", pos))
    if cfg.mounts or not cfg.grid_step:
        for obj in find_mounts(scene, cfg.mounts):
            spots.append((obj.name, mount_position(obj)))
    if not spots:
        raise SceneError(f"scene {scene.name!r} has no LiDAR mounts: mark pole objects with the "
                         "custom property rls_mount = True, name them with --mount, or use --grid")
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
    return out


def static_geometry(depsgraph, keep_traffic=False):
    """World geometry of everything rendered except traffic; (geometry, hidden names)."""
    instances, materials, _ = read_instances(depsgraph)
    traffic = set() if keep_traffic else {label_id(n) for n in TRAFFIC_LABELS}
    hidden = sorted(i.key for i in instances if i.label in traffic)
    static = [i for i in instances if i.label not in traffic]
    return world_geometry(static, object_table(static), materials), hidden


def run_study(scene, cfg, progress=None):
    """Scan every candidate and search placements; returns a ``StudyResult``.

    ``progress(done, total, candidate, eta_seconds)`` is called after each scan."""
    t0 = time.perf_counter()
    preset = get_preset(cfg.device)
    lob_obj = find_lob(scene, cfg.lob)
    polygon = lob_polygon_world(lob_obj)
    layout = DiskLayout.make(polygon, cfg.disks, cfg.radius, cfg.disk_seed, cfg.disk_placement)
    label_ids = resolve_labels(cfg.labels)
    cands = make_candidates(scene, cfg, polygon)
    spots = len({c.mount for c in cands}) if cfg.one_per_mount else len(cands)
    for k in cfg.k:
        if k < 1:
            raise SceneError(f"k must be at least 1, got {k}")
        if k > spots:
            raise SceneError(f"k = {k} needs {k} distinct mounts; the candidates have {spots}"
                             + (" (--allow-shared-mounts lets a mount hold several)"
                                if cfg.one_per_mount and k <= len(cands) else ""))
    frame = scene.frame_current if cfg.frame is None else int(cfg.frame)
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry, hidden = static_geometry(depsgraph, cfg.keep_traffic)
    try:
        factory, notice = caster_factory(cfg.backend)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    settings = ScanSettings(seed=cfg.scan_seed, frame_space="world", noise=cfg.noise,
                            dropout=cfg.dropout, motion="snapshot", ghosting=cfg.ghosting)
    _, rmax = resolve_range(preset, settings)
    centre = np.r_[polygon.mean(axis=0), 0.0]
    reach = max(np.linalg.norm(np.array(c.position) - centre) for c in cands) + rmax + 1.0
    session = ScanSession(factory)
    t_build = time.perf_counter()
    prepared = session.prepared(geometry, centre, reach)
    t_scan = time.perf_counter()
    pattern = preset.pattern(frame)
    xy_all, counts = [], []
    for i, c in enumerate(cands):
        t = time.perf_counter()
        result = scan_frame(prepared, pattern, c.pose, preset, settings, frame=frame,
                            sensor=c.name)
        xy = layout.select([result.points], label_ids)
        xy_all.append(xy)
        counts.append(layout.counts(xy))
        c.n_points, c.scan_points, c.rays = len(xy), len(result.points), result.rays
        c.seconds = time.perf_counter() - t
        if progress is not None:
            elapsed = time.perf_counter() - t_scan
            progress(i + 1, len(cands), c, elapsed / (i + 1) * (len(cands) - i - 1))
    t_search = time.perf_counter()
    groups = [c.mount for c in cands] if cfg.one_per_mount else None
    cc = CandidateCounts([c.n_points for c in cands], np.array(counts), layout.area_m2, layout.p,
                         groups)
    for c, p in zip(cands, cc.evaluate([(c.index,) for c in cands])):
        c.infra_d, c.infra_nuc = p.infra_d, p.infra_nuc
    searches = {}
    for k in cfg.k:
        try:
            searches[k] = cc.search(k, exhaustive_limit=cfg.exhaustive_limit)
        except ValueError as exc:
            raise SceneError(f"k = {k}: {exc}") from None
    t_end = time.perf_counter()
    timing = {"total_s": t_end - t0, "build_s": t_scan - t_build, "scan_s": t_search - t_scan,
              "search_s": t_end - t_search,
              "per_candidate_s": (t_search - t_scan) / max(len(cands), 1)}
    return StudyResult(cfg, scene.name, frame,
                       {"id": preset.id, "name": preset.name, "source": preset.source},
                       polygon, layout, cands, cc, searches, xy_all, timing, hidden,
                       prepared.backend, session.builds, [notice] if notice else [])
