"""Scanning a study's candidates (``StudyScanner``): the static geometry is read once
and one ray-casting structure, built around the region's centre with a reach that
covers every candidate, serves all candidates. A candidate keeps only its points'
counts per disk (``CandidateScan``), from a frame that assembles only x, y and label,
and of a candidate outside the region only the rays toward it are cast
(``polygon.polygon_arc``); with traffic frames, its points on each vehicle too.
``study_inputs`` makes what every scanner of the same study shares (device, region,
disks, candidates), so workers build twins of the scanner here."""

import dataclasses
import time

import numpy as np

from ..casting import caster_factory
from ..device.presets import get_preset
from ..errors import SceneError
from ..labels import label_id
from ..metrics.infra import resolve_labels
from ..metrics.polygon import in_arc, points_in_polygon, polygon_arc
from ..scan.dask_run import available_memory
from ..scan.frame import scan_frame, sensor_axes
from ..scan.session import ScanSession
from ..scan.device_values import device_values
from ..scan.settings import ScanSettings
from ..scene.instances import object_table, world_geometry
from ..scene.motion import Track
from ..world.bodies import RigidBodies
from .placement import DiskLayout
from .candidates import candidate_spots, make_candidates
from .config import TRAFFIC_LABELS
from ..evaluate.detector import RoadsideDetector
from ..scan.background_sweeps import road_user_ids, sweep_seed
from .detection import CandidateEvaluation, evaluate_candidate, frame_truth, truth_types


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
    evaluation: "CandidateEvaluation" = None  # with evaluation frames (``evaluation``)


# The point fields a study gathers: where a point is and what it hit (counted in the
# region), and with the traffic in view whose it is and whether it is a ghost.
STUDY_FIELDS = ("x", "y", "label")


TRAFFIC_FIELDS = ("instance", "ghost")
# ... and in the frames scored by detection, where each point is
EVALUATE_FIELDS = ("x", "y", "z", "instance", "ghost")


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
        self.notices += list(getattr(scene, "warnings", ()))  # what the scene left out
        self.settings = ScanSettings(seed=cfg.scan_seed, frame_space="world", noise=cfg.noise,
                                     dropout=cfg.dropout, motion="snapshot",
                                     ghosting=cfg.ghosting)
        # the device after the study's settings, once: every candidate's frames read it
        self.values = device_values(preset, self.settings)
        rmax = self.values.max_range_m
        centre = np.r_[polygon.mean(axis=0), 0.0]
        reach = max(np.linalg.norm(np.array(c.position) - centre) for c in candidates) + rmax + 1.0
        self.session = ScanSession(self.backend_cls)
        t = time.perf_counter()
        self._scene, self._around = scene, (centre, reach)
        self.prepared = self.session.prepared(geometry, centre, reach)
        layout.prepare()  # the disks' and the outline's grids, once per study
        self.build_s = time.perf_counter() - t
        if not cfg.traffic_frames:
            # Each candidate casts its rays once: a kept cast would never be asked for
            # again, and keeping it costs a copy of it per candidate (the traffic frames
            # reuse theirs: the static scene seen from the same pose).
            self.prepared.reuse_casts = False
        self.traffic, self.vehicle_frames = [], []
        self.truths = {}  # evaluation frame -> evaluation.FrameTruth
        self._arcs = {}  # the region's arc of directions from each mount
        if cfg.traffic_frames:
            self._traffic(scene)
            scene.set_frame(self.frame)
        self.detector = cfg.detector
        if self.detector is None and cfg.evaluate_frames:
            self.detector = RoadsideDetector(
                noise_sigma=self.values.noise_sigma_m,
                types=truth_types(self.truths))
        self._empty = None  # the scene without road users, when the static one has them

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
            if int(f) in self.cfg.evaluate_frames:
                self.truths[int(f)] = frame_truth(f, insts, objects)
        if not self.vehicle_frames:  # nothing to score: say so before any scan
            frames = self.cfg.traffic_frames
            span = f"{frames[0]}" if len(frames) == 1 else f"{min(frames)}-{max(frames)}"
            raise SceneError(
                f"--traffic {span}: no object labelled {'/'.join(self.cfg.visibility_labels)} "
                f"has its centre in the region in these frames, so visibility has nothing "
                f"to score: choose frames with traffic in the region, or leave out --traffic")

    def _static(self, cand):
        """(xy of the kept points, the frame's ``ScanResult``) of candidate ``cand``
        over the static scene: only x, y and label are gathered, and only the rays that
        may put a point in the region are cast (``rays_toward_region``)."""
        result = scan_frame(self.prepared, self.preset.pattern(self.frame), cand.pose,
                            self.values, self.settings, frame=self.frame, sensor=cand.name,
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
        if self.traffic or self.values.beam is not None:
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

    def background_sweeps(self, cand):
        """Candidate ``cand``'s sweeps of the scene with every road user hidden (world x y
        z, (N, 3) each): ``cfg.background_sweeps`` scans of the study's frame, each with
        its own seed (``background_sweeps.sweep_seed``): what a deployed unit's
        background holds."""
        prepared = self.prepared
        if self.cfg.keep_traffic:  # the study's static scene holds the traffic
            if self._empty is None:
                geometry, _ = self._scene.static_geometry(road_user_ids())
                self._empty = self.session.prepared(geometry, *self._around)
            prepared = self._empty
        out = []
        for k in range(int(self.cfg.background_sweeps)):
            settings = dataclasses.replace(self.settings,
                                           seed=sweep_seed(self.cfg.scan_seed, k))
            p = scan_frame(prepared, self.preset.pattern(self.frame), cand.pose, self.values,
                           settings, frame=self.frame, sensor=cand.name,
                           fields=("x", "y", "z")).points
            out.append(np.stack([p["x"], p["y"], p["z"]], 1).astype(np.float64))
        return out

    def scan(self, cand):
        """A ``CandidateScan`` of candidate ``cand``."""
        t = time.perf_counter()
        xy, result = self._static(cand)
        n_points, counts = len(xy), self.layout.counts(xy)
        scan_points, rays = len(result.points), result.rays
        del xy, result
        seen, frame_points = None, {}
        if self.traffic:
            seen = np.zeros(len(self.vehicle_frames), np.int64)
            for f, group, scored in self.traffic:
                evaluated = f in self.truths
                res = scan_frame(self.prepared, self.preset.pattern(f), cand.pose, self.values,
                                 self.settings, frame=f, sensor=cand.name,
                                 moving=[group] if group is not None else [],
                                 fields=EVALUATE_FIELDS if evaluated else TRAFFIC_FIELDS)
                p = res.points
                instance = p["instance"][p["ghost"] == 0]
                for j, iid in scored:
                    seen[j] = int(np.count_nonzero(instance == iid))
                if evaluated:
                    frame_points[f] = (np.stack([p["x"], p["y"], p["z"]], 1).astype(np.float64),
                                       p["instance"], p["ghost"])
        evaluation = None
        if frame_points:
            sweeps = self.background_sweeps(cand) \
                if self.cfg.evaluate_background == "empty" else None
            evaluation = evaluate_candidate(self.detector, cand.name, cand.pose, frame_points,
                                            self.truths, sweeps)
        return CandidateScan(cand.index, n_points, counts, scan_points, rays,
                             time.perf_counter() - t, seen, evaluation)


@dataclasses.dataclass
class StudyInputs:
    preset: object
    polygon: np.ndarray
    layout: DiskLayout
    candidates: list


def study_inputs(scene, cfg):
    """The device, the region, its disks and the candidates of a study (the same
    wherever they are made from the same scene and settings), with the k checked."""
    from ..device.modes import with_modes

    preset = with_modes(get_preset(cfg.device), getattr(cfg, "rotation_hz", None),
                        getattr(cfg, "lidar_mode", None))
    polygon = scene.region(cfg.lob)
    layout = DiskLayout.make(polygon, cfg.disks, cfg.radius, cfg.disk_seed, cfg.disk_placement)
    cands = make_candidates(candidate_spots(scene, cfg, polygon, available_memory()), cfg,
                            polygon)
    spots = len({c.mount for c in cands}) if cfg.one_per_mount else len(cands)
    for k in cfg.k:
        if k < 1:
            raise SceneError(f"k must be at least 1, got {k}")
        if k > spots:
            raise SceneError(f"k = {k} needs {k} distinct mounts; the candidates have {spots}"
                             + (" (--allow-shared-mounts lets a mount hold several)"
                                if cfg.one_per_mount and k <= len(cands) else ""))
    return StudyInputs(preset, polygon, layout, cands)
