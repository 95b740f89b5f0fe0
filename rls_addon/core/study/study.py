"""Placement study: scan every candidate placement of one device over the static scene
once, measure InfraD / InfraNUC in the InfraLOB, and search sets of k sensors
(``placement``).

As in the paper, traffic is removed before the metrics are taken: the study scene
leaves objects labelled vehicle or pedestrian out of the geometry (the scene itself is
not changed). The static geometry is read once and one ray-casting structure, built
around the region's centre with a reach that covers every candidate, serves all
candidates.

The scene comes in through a small interface (``StudyScene``): the Blender layer's
(``blender.study.BlenderStudyScene``) reads a .blend; tests hand in fakes.
"""

import dataclasses
import math
import time
from typing import Protocol

import numpy as np

from ..world.bodies import RigidBodies
from ..casting import caster_factory
from ..errors import RegionError, SceneError, SettingsError
from ..physics.footprint import beam_of
from ..scan.frame import scan_frame, sensor_axes
from ..scene.instances import object_table, world_geometry
from ..labels import label_id
from ..scene.motion import Track
from ..metrics.infra import (
    DEFAULT_CELL_M,
    DEFAULT_DISKS,
    DEFAULT_RADIUS_M,
    DEFAULT_SEED,
    density_map,
    resolve_labels,
)
from .placement import DEFAULT_EXHAUSTIVE_LIMIT, CandidateCounts, DiskLayout
from ..metrics.polygon import as_polygon, in_arc, points_in_polygon, polygon_arc
from ..device.presets import get_preset
from ..scan.session import ScanSession
from ..scan.settings import ScanSettings, resolve_range
from ..metrics.visibility import THRESHOLDS, VisibilityCounts, ranks

TRAFFIC_LABELS = ("vehicle", "pedestrian")


class StudyScene(Protocol):
    """What a study asks of a scene."""

    name: str

    def current_frame(self) -> int: ...

    def set_frame(self, frame: int) -> None: ...

    def region(self, name: str | None) -> np.ndarray:
        """(N, 2) world xy outline of the InfraLOB ``name`` (None: the one marked)."""

    def mounts(self, names: tuple) -> list:
        """[(name, (x, y, z))] of the mounts ``names`` (empty: every marked mount)."""

    def static_geometry(self, hidden_labels: set) -> tuple:
        """(SceneGeometry of everything rendered but objects with these label ids,
        sorted names of the objects left out)."""

    def traffic(self, frames: tuple, labels: set) -> dict:
        """{frame: source.SceneRead} of the objects with these label ids at each frame
        (their meshes in their own frames, their matrices at that frame)."""


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
    # Placements scored with the traffic in view (``visibility``): these frames of the
    # scene's animated traffic, and the labels whose objects are scored
    traffic_frames: tuple = ()
    visibility_labels: tuple = ("vehicle",)
    visibility_thresholds: tuple = THRESHOLDS


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
    searches: dict                  # k -> placement.SearchResult
    timing: dict
    hidden_traffic: list
    backend: str
    structure_builds: int
    notices: list
    visibility: "TrafficVisibility" = None  # with cfg.traffic_frames
    # The study's scanner: the candidates keep only counts, so a density map scans its
    # set's members again (the same seeds: the same points). Kept: the points of those
    # scanned again, per candidate (a handful: the members of the sets drawn).
    scanner: "StudyScanner" = dataclasses.field(default=None, repr=False)
    kept: dict = dataclasses.field(default_factory=dict, repr=False)

    def kept_xy(self, index):
        """(n, 2) world xy of candidate ``index``'s points in the region with a counted
        label, from the scanner (once per candidate, then kept)."""
        got = self.kept.get(index)
        if got is None:
            if self.scanner is None:
                raise SceneError("this study result has no scanner to scan its candidates again")
            got = self.kept[index] = self.scanner.kept_xy(self.candidates[index])
        return got

    def density(self, members):
        """The density map (``metrics.DensityMap``) of the set ``members``."""
        xy = (np.concatenate([self.kept_xy(i) for i in members]) if len(members)
              else np.empty((0, 2)))
        return density_map(xy, self.polygon, self.config.cell)


def make_candidates(spots, cfg, polygon):
    """Candidate placements: spots [(name, (x, y, z))] x pitches x yaws."""
    centre = polygon.mean(axis=0)
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


def candidate_spots(scene, cfg, polygon):
    """[(name, (x, y, z))]: grid points (``cfg.grid_step``) and/or the scene's mounts."""
    spots = []
    if cfg.grid_step:
        for j, pos in enumerate(grid_positions(polygon, cfg.grid_step, cfg.grid_heights,
                                               cfg.grid_margin)):
            spots.append((f"grid{j:03d}@({pos[0]:g},{pos[1]:g},{pos[2]:g})", pos))
    if cfg.mounts or not cfg.grid_step:
        spots += scene.mounts(tuple(cfg.mounts))
    if not spots:
        raise SceneError(f"scene {scene.name!r} has no LiDAR mounts: mark pole objects with the "
                         "custom property rls_mount = True, name them with --mount, or use --grid")
    return spots


@dataclasses.dataclass
class CandidateScan:
    """What one candidate's scans give the study: counts only, no points (a study of
    thousands of candidates keeps a few tens of KB each; see ``StudyResult.kept_xy``
    for the points of the few a density map needs)."""

    index: int
    n_points: int            # kept points in the InfraLOB (traffic removed)
    disk_counts: np.ndarray  # (D,) of them per disk
    scan_points: int
    rays: int
    seconds: float
    vehicle_points: np.ndarray = None  # (J,) points on each vehicle-frame (with traffic)


# The point fields a study gathers: where a point is and what it hit (counted in the
# region), and with the traffic in view whose it is and whether it is a ghost.
STUDY_FIELDS = ("x", "y", "label")
TRAFFIC_FIELDS = ("instance", "ghost")


class StudyScanner:
    """Scans the candidates of one study: the static scene (traffic removed) prepared
    once around the region, and with ``cfg.traffic_frames`` the traffic of each of
    those frames built once as bodies that every candidate sees. ``scan(candidate)``
    is independent of the other candidates (a run may split them over workers)."""

    def __init__(self, scene, cfg, preset, polygon, layout, candidates, factory=caster_factory):
        self.cfg, self.preset, self.polygon, self.layout = cfg, preset, polygon, layout
        self.label_ids = resolve_labels(cfg.labels)
        self.frame = scene.current_frame() if cfg.frame is None else int(cfg.frame)
        scene.set_frame(self.frame)
        hide = set() if cfg.keep_traffic else {label_id(n) for n in TRAFFIC_LABELS}
        geometry, self.hidden = scene.static_geometry(hide)
        self.backend_cls, notice = factory(cfg.backend)
        self.notices = [notice] if notice else []
        self.settings = ScanSettings(seed=cfg.scan_seed, frame_space="world", noise=cfg.noise,
                                     dropout=cfg.dropout, motion="snapshot",
                                     ghosting=cfg.ghosting)
        _, rmax = resolve_range(preset, self.settings)
        centre = np.r_[polygon.mean(axis=0), 0.0]
        reach = max(np.linalg.norm(np.array(c.position) - centre) for c in candidates) + rmax + 1.0
        self.session = ScanSession(self.backend_cls)
        t = time.perf_counter()
        self.prepared = self.session.prepared(geometry, centre, reach)
        layout.prepare()  # the disks' and the outline's grids, once per study
        self.build_s = time.perf_counter() - t
        if not cfg.traffic_frames:
            # Each candidate casts its rays once: a kept cast would never be asked for
            # again, and keeping it costs a copy of it per candidate (the traffic frames
            # reuse theirs: the static scene seen from the same pose).
            self.prepared.reuse_casts = False
        self.traffic, self.vehicle_frames = [], []
        self._arcs = {}  # the region's arc of directions from each mount
        if cfg.traffic_frames:
            self._traffic(scene)
            scene.set_frame(self.frame)

    def _traffic(self, scene):
        """Per traffic frame: the traffic as still bodies, and the vehicle-frames to score
        (vehicles whose box centre is in the region)."""
        vehicles = {label_id(n) for n in self.cfg.visibility_labels}
        traffic_ids = {label_id(n) for n in TRAFFIC_LABELS} | vehicles
        for f, read in scene.traffic(tuple(self.cfg.traffic_frames), traffic_ids).items():
            insts = read.instances
            objects = object_table(insts)
            parts = [(world_geometry(insts, objects, read.materials, select={k}, local=True),
                      Track.fixed(inst.matrix)) for k, inst in enumerate(insts)]
            group = RigidBodies(parts, self.backend_cls) if parts else None
            scored = []
            for k, inst in enumerate(insts):
                if inst.label not in vehicles or not len(inst.vertices):
                    continue
                centre = inst.matrix[:3, :3] @ ((inst.vertices.min(0) + inst.vertices.max(0)) / 2) \
                    + inst.matrix[:3, 3]
                if points_in_polygon(centre[None, :2], self.polygon)[0]:
                    scored.append((len(self.vehicle_frames), objects[k].instance))
                    self.vehicle_frames.append((int(f), inst.key))
            self.traffic.append((int(f), group, scored))

    def _static(self, cand):
        """(xy of the kept points, the frame's ``ScanResult``) of candidate ``cand``
        over the static scene: only x, y and label are gathered, and only the rays that
        may put a point in the region are cast (``rays_toward_region``)."""
        result = scan_frame(self.prepared, self.preset.pattern(self.frame), cand.pose,
                            self.preset, self.settings, frame=self.frame, sensor=cand.name,
                            fields=STUDY_FIELDS, rays=self.rays_toward_region(cand))
        return self.layout.select([result.points], self.label_ids), result

    def rays_toward_region(self, cand):
        """Indices of candidate ``cand``'s rays whose half-lines cross the region seen
        from above (``polygon.polygon_arc``, ``in_arc``), or None (all of them). Every point of
        a ray lies on its half-line (its range noise, a ghost's total path, a false
        return from the air: all along the ray), so the others cannot count, and each
        ray cast returns what it returns in the whole frame (``scan_frame``'s
        ``rays``): the counts are the whole frame's. A candidate outside the region,
        which sees it in a quarter of its turn, casts a quarter of its rays. All rays
        are cast with beam footprints (a footprint needs its neighbours) and with
        traffic frames (they reuse the candidate's whole static cast)."""
        if self.traffic or beam_of(self.preset, self.settings) is not None:
            return None
        where = tuple(cand.pose[:2, 3])
        if where not in self._arcs:  # per mount: its pitches and yaws share it
            self._arcs[where] = polygon_arc(self.polygon, where)
        if self._arcs[where] is None:
            return None
        rot = sensor_axes(cand.pose)[1]
        return in_arc(self._arcs[where], self.preset.pattern(self.frame).rotated(rot))

    def kept_xy(self, cand):
        """(n, 2) world xy of candidate ``cand``'s points in the region with a counted
        label: its scan of the static scene again, with the same seed (the points its
        counts came from)."""
        return self._static(cand)[0]

    def scan(self, cand):
        """A ``CandidateScan`` of candidate ``cand``."""
        t = time.perf_counter()
        xy, result = self._static(cand)
        n_points, counts = len(xy), self.layout.counts(xy)
        scan_points, rays = len(result.points), result.rays
        del xy, result
        seen = None
        if self.traffic:
            seen = np.zeros(len(self.vehicle_frames), np.int64)
            for f, group, scored in self.traffic:
                res = scan_frame(self.prepared, self.preset.pattern(f), cand.pose, self.preset,
                                 self.settings, frame=f, sensor=cand.name,
                                 moving=[group] if group is not None else [],
                                 fields=TRAFFIC_FIELDS)
                instance = res.points["instance"][res.points["ghost"] == 0]
                for j, iid in scored:
                    seen[j] = int(np.count_nonzero(instance == iid))
        return CandidateScan(cand.index, n_points, counts, scan_points, rays,
                             time.perf_counter() - t, seen)


@dataclasses.dataclass
class StudyInputs:
    preset: object
    polygon: np.ndarray
    layout: DiskLayout
    candidates: list


def study_inputs(scene, cfg):
    """The device, the region, its disks and the candidates of a study (the same
    wherever they are made from the same scene and settings), with the k checked."""
    preset = get_preset(cfg.device)
    polygon = scene.region(cfg.lob)
    layout = DiskLayout.make(polygon, cfg.disks, cfg.radius, cfg.disk_seed, cfg.disk_placement)
    cands = make_candidates(candidate_spots(scene, cfg, polygon), cfg, polygon)
    spots = len({c.mount for c in cands}) if cfg.one_per_mount else len(cands)
    for k in cfg.k:
        if k < 1:
            raise SceneError(f"k must be at least 1, got {k}")
        if k > spots:
            raise SceneError(f"k = {k} needs {k} distinct mounts; the candidates have {spots}"
                             + (" (--allow-shared-mounts lets a mount hold several)"
                                if cfg.one_per_mount and k <= len(cands) else ""))
    return StudyInputs(preset, polygon, layout, cands)


def run_study(scene, cfg, progress=None, factory=caster_factory, scan_all=None):
    """Scan every candidate of ``scene`` (a ``StudyScene``) and search placements;
    returns a ``StudyResult``.

    ``progress(done, total, candidate, eta_seconds)`` is called after each scan.
    ``scan_all(scanner, candidates, on_scan)``: how the candidates are scanned (default:
    one after another here; a sharded run hands them to workers); it calls
    ``on_scan(CandidateScan)`` for each, in any order."""
    t0 = time.perf_counter()
    inputs = study_inputs(scene, cfg)
    preset, polygon, layout, cands = inputs.preset, inputs.polygon, inputs.layout, inputs.candidates
    scanner = StudyScanner(scene, cfg, preset, polygon, layout, cands, factory)
    t_scan = time.perf_counter()
    # Only counts are kept, written in place as the scans arrive: no points, and no
    # second copy of the disk counts when the search starts.
    n_points = np.zeros(len(cands), np.int64)
    disk_counts = np.zeros((len(cands), len(layout.centres)), np.int64)
    vehicle_points = (np.zeros((len(cands), len(scanner.vehicle_frames)), np.int64)
                      if scanner.traffic else None)
    scanned = np.zeros(len(cands), bool)

    def on_scan(got):
        i = got.index
        scanned[i] = True
        n_points[i], disk_counts[i] = got.n_points, got.disk_counts
        if vehicle_points is not None:
            vehicle_points[i] = got.vehicle_points
        c = cands[i]
        c.n_points, c.scan_points, c.rays, c.seconds = (got.n_points, got.scan_points,
                                                        got.rays, got.seconds)
        if progress is not None:
            done = int(np.count_nonzero(scanned))
            elapsed = time.perf_counter() - t_scan
            progress(done, len(cands), c, elapsed / done * (len(cands) - done))

    if scan_all is None:
        for c in cands:
            on_scan(scanner.scan(c))
    else:
        scan_all(scanner, cands, on_scan)
    if not scanned.all():
        raise SceneError(f"{int(np.count_nonzero(~scanned))} of {len(cands)} candidates "
                         "were not scanned")
    t_search = time.perf_counter()
    groups = [c.mount for c in cands] if cfg.one_per_mount else None
    cc = CandidateCounts(n_points, disk_counts, layout.area_m2, layout.p, groups)
    for c, p in zip(cands, cc.evaluate([(c.index,) for c in cands])):
        c.infra_d, c.infra_nuc = p.infra_d, p.infra_nuc
    searches = {}
    for k in cfg.k:
        try:
            searches[k] = cc.search(k, exhaustive_limit=cfg.exhaustive_limit)
        except SettingsError as exc:
            raise SceneError(f"k = {k}: {exc}") from None
    vis = None
    if scanner.traffic:
        vis = TrafficVisibility.of(scanner, cands, vehicle_points, groups, searches, cfg)
    t_maps = time.perf_counter()
    result = StudyResult(cfg, scene.name, scanner.frame,
                         {"id": preset.id, "name": preset.name, "source": preset.source},
                         polygon, layout, cands, cc, searches, {}, scanner.hidden,
                         scanner.prepared.backend, scanner.session.builds, scanner.notices, vis,
                         scanner)
    # The density maps the report draws (the best set of each k): their members are
    # scanned again here with this process's scanner (in a run on workers the counts
    # came from its twins, built from the same scene and settings: the same points).
    for k in sorted(searches):
        for i in searches[k].best.members:
            result.kept_xy(i)
    t_end = time.perf_counter()
    result.timing.update({
        "total_s": t_end - t0, "build_s": scanner.build_s, "scan_s": t_search - t_scan,
        "search_s": t_maps - t_search, "maps_s": t_end - t_maps,
        "per_candidate_s": (t_search - t_scan) / max(len(cands), 1)})
    return result


@dataclasses.dataclass
class TrafficVisibility:
    """The study's scores with the traffic in view (``visibility``)."""

    frames: list
    vehicle_frames: list          # [(frame, object key)]
    counts: VisibilityCounts
    candidates: list              # Visibility per candidate
    rank_infra_d: np.ndarray      # per candidate: 1 = densest
    rank_visibility: np.ndarray   # per candidate: 1 = best seen traffic
    sets: dict                    # k -> {members tuple: Visibility} of the evaluated sets
    best: dict                    # k -> Visibility of the best set by visibility

    @classmethod
    def of(cls, scanner, cands, vehicle_points, groups, searches, cfg):
        """``vehicle_points``: (candidates, vehicle-frames) points of each candidate on
        each vehicle-frame."""
        counts = VisibilityCounts(np.asarray(vehicle_points),
                                  [key for _, key in scanner.vehicle_frames], groups,
                                  cfg.visibility_thresholds)
        per = counts.evaluate([(c.index,) for c in cands])
        sets = {k: {v.members: v for v in counts.evaluate([p.members for p in s.evaluated])}
                for k, s in searches.items()}
        best = {k: counts.best(k, cfg.exhaustive_limit) for k in searches}
        return cls([f for f, _, _ in scanner.traffic], list(scanner.vehicle_frames), counts, per,
                   ranks([c.infra_d for c in cands]),
                   ranks([v.score + 1e-9 * v.mean_points for v in per]), sets, best)


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


def parse_values(text, what="values"):
    """'10' -> [10.0]; '0,10,20' -> list; '0:30:10' -> 0,10,20,30 (inclusive range)."""
    if isinstance(text, (int, float)):
        return [float(text)]
    text = str(text).strip()
    bad = RegionError(f"{what}: expected V, V1,V2,... or START:STOP:STEP, got {text!r}")
    try:
        if ":" in text:
            parts = [float(t) for t in text.split(":")]
            if len(parts) != 3 or parts[2] <= 0:
                raise bad
            a, b, step = parts
            count = int(math.floor((b - a) / step + 1e-9)) + 1
            if count < 1:
                raise bad
            return [round(a + i * step, 9) for i in range(count)]
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise bad from None
    if not vals:
        raise RegionError(f"{what}: no values in {text!r}")
    return vals


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


def facing_yaw_deg(position, target_xy):
    """Yaw (degrees) that points +X from ``position`` towards ``target_xy``."""
    dx, dy = target_xy[0] - position[0], target_xy[1] - position[1]
    if abs(dx) < 1e-12 and abs(dy) < 1e-12:
        return 0.0
    return math.degrees(math.atan2(dy, dx))
