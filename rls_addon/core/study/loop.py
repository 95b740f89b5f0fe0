"""The placement study's loop (``run_study``): scan every candidate of a
``scene.source.StudyScene`` once, measure InfraD / InfraNUC in the InfraLOB, search sets
of k sensors (``placement``), and score candidates and sets by traffic visibility when
traffic frames are given. The scene comes in through ``StudyScene``: the Blender
layer's (``blender.study.BlenderStudyScene``) reads a .blend; tests hand in fakes."""

import dataclasses
import time

import numpy as np

from ..casting import caster_factory
from ..errors import SceneError, SettingsError
from ..labels import label_name
from ..metrics.infra import density_map
from ..metrics.visibility import VisibilityCounts, ranks
from ..scene.traffic_keys import check_keyed, source_span
from .placement import CandidateCounts, DiskLayout
from .config import StudyConfig
from .evaluation import StudyEvaluation
from .scanner import StudyScanner, study_inputs


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
    evaluation: "StudyEvaluation" = None   # with cfg.evaluate_frames
    # The study's scanner: the candidates keep only counts, so a density map scans its
    # set's members again (the same seeds: the same points). Kept: the points of those
    # scanned again, per candidate (a handful: the members of the sets drawn).
    scanner: "StudyScanner" = dataclasses.field(default=None, repr=False)
    kept: dict = dataclasses.field(default_factory=dict, repr=False)
    scene_file: str = ""  # the scene's file name (its charts' titles name it)

    @property
    def title(self):
        """What charts call the scene: its file's name, else the scene's own."""
        return self.scene_file or self.scene

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


def run_study(scene, cfg, progress=None, factory=caster_factory, scan_all=None):
    """Scan every candidate of ``scene`` (a ``StudyScene``) and search placements;
    returns a ``StudyResult``.

    ``progress(done, total, candidate, eta_seconds)`` is called after each scan.
    ``scan_all(scanner, candidates, on_scan)``: how the candidates are scanned (default:
    one after another here; a sharded run hands them to workers); it calls
    ``on_scan(CandidateScan)`` for each, in any order."""
    run = StudyRun(scene, cfg, progress, factory)
    if scan_all is None:
        while not run.scanned_all:
            run.step()
    else:
        scan_all(run.scanner, run.candidates, run.on_scan)
    return run.finish()


class StudyRun:
    """One study in steps, for a caller that must stay responsive between them (the
    Study operator runs a step per timer event; ``run_study`` runs them all):
    making it reads the scene and builds the ray-casting structure, ``step()`` scans
    the next candidate, ``finish()`` searches the sets and returns the
    ``StudyResult``. The same steps in any caller give the same numbers. A run
    dropped before ``finish()`` has changed nothing but the scene's frame (the
    caller puts it back)."""

    def __init__(self, scene, cfg, progress=None, factory=caster_factory):
        self.t0 = time.perf_counter()
        self.scene, self.cfg, self.progress = scene, cfg, progress
        span = source_span(scene)
        check_keyed(cfg.traffic_frames, span, "traffic frames")
        check_keyed(cfg.evaluate_frames, span, "evaluation frames")
        self.inputs = inputs = study_inputs(scene, cfg)
        cands, layout = inputs.candidates, inputs.layout
        self.candidates = cands
        self.scanner = StudyScanner(scene, cfg, inputs.preset, inputs.polygon, layout, cands,
                                    factory)
        self.t_scan = time.perf_counter()
        # Only counts are kept, written in place as the scans arrive: no points, and no
        # second copy of the disk counts when the search starts.
        self.n_points = np.zeros(len(cands), np.int64)
        self.disk_counts = np.zeros((len(cands), len(layout.centres)), np.int64)
        self.vehicle_points = (np.zeros((len(cands), len(self.scanner.vehicle_frames)),
                                        np.int64) if self.scanner.traffic else None)
        self.scanned = np.zeros(len(cands), bool)
        self.evaluations = [None] * len(cands)

    @property
    def total(self):
        return len(self.candidates)

    @property
    def done(self):
        return int(np.count_nonzero(self.scanned))

    @property
    def scanned_all(self):
        return bool(self.scanned.all())

    def step(self):
        """Scan the next candidate not yet scanned; returns it."""
        c = self.candidates[int(np.argmin(self.scanned))]
        self.on_scan(self.scanner.scan(c))
        return c

    def on_scan(self, got):
        """Keep a ``CandidateScan``'s counts (from ``step`` or from a ``scan_all``)."""
        i = got.index
        self.scanned[i] = True
        self.n_points[i], self.disk_counts[i] = got.n_points, got.disk_counts
        if self.vehicle_points is not None:
            self.vehicle_points[i] = got.vehicle_points
        self.evaluations[i] = got.evaluation
        c = self.candidates[i]
        c.n_points, c.scan_points, c.rays, c.seconds = (got.n_points, got.scan_points,
                                                        got.rays, got.seconds)
        if self.progress is not None:
            done = self.done
            elapsed = time.perf_counter() - self.t_scan
            self.progress(done, self.total, c, elapsed / done * (self.total - done))

    def finish(self):
        """Search the sets of each k (and score visibility and detection when asked):
        the ``StudyResult``."""
        cfg, cands, scanner = self.cfg, self.candidates, self.scanner
        layout, preset = self.inputs.layout, self.inputs.preset
        if not self.scanned_all:
            raise SceneError(f"{int(np.count_nonzero(~self.scanned))} of {len(cands)} "
                             "candidates were not scanned")
        self._refuse_empty_region()
        t_search = time.perf_counter()
        groups = [c.mount for c in cands] if cfg.one_per_mount else None
        cc = CandidateCounts(self.n_points, self.disk_counts, layout.area_m2, layout.p, groups)
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
            vis = TrafficVisibility.of(scanner, cands, self.vehicle_points, groups, searches,
                                       cfg)
        evaluation = None
        if cfg.evaluate_frames:
            t_eval = time.perf_counter()
            evaluation = StudyEvaluation.of(cfg, scanner, cands, self.evaluations, searches,
                                            vis)
            scanner.notices.append(f"evaluation: {len(cands)} candidates and "
                                   f"{len(evaluation.sets)} sets scored by detection in "
                                   f"{time.perf_counter() - t_eval:.1f} s; the detector's "
                                   f"background: {evaluation.background['what']}")
            scanner.notices += evaluation.notices
        t_maps = time.perf_counter()
        scene = self.scene
        result = StudyResult(cfg, scene.name, scanner.frame,
                             {"id": preset.id, "name": preset.name, "source": preset.source},
                             self.inputs.polygon, layout, cands, cc, searches, {},
                             scanner.hidden, scanner.prepared.backend, scanner.session.builds,
                             scanner.notices, vis, evaluation, scanner,
                             scene_file=getattr(scene, "file", "") or "")
        # The density maps the report draws (the best set of each k): their members are
        # scanned again here with this process's scanner (in a run on workers the counts
        # came from its twins, built from the same scene and settings: the same points).
        for k in sorted(searches):
            for i in searches[k].best.members:
                result.kept_xy(i)
        t_end = time.perf_counter()
        result.timing.update({
            "total_s": t_end - self.t0, "build_s": scanner.build_s,
            "scan_s": t_search - self.t_scan, "search_s": t_maps - t_search,
            "maps_s": t_end - t_maps,
            "per_candidate_s": (t_search - self.t_scan) / max(len(cands), 1)})
        return result


    def _refuse_empty_region(self):
        """``SceneError`` when no candidate put a counted point in the region, or none in
        any disk: every set would score InfraD 0 and no InfraNUC, and one of them be
        named best (``rls metrics`` refuses the same clouds)."""
        layout = self.inputs.layout
        names = ", ".join(label_name(i) for i in self.scanner.label_ids)
        if not self.n_points.any():
            raise SceneError(
                f"no candidate puts a point labelled {names} in the region "
                f"({layout.area_m2:.1f} m^2): every placement would score InfraD 0, with no "
                "InfraNUC; check that the region lies over the road within the device's "
                "range of the mounts, and the labels (--labels)")
        if not self.disk_counts.any():
            raise SceneError(
                f"none of the {len(layout.centres)} disks holds any of the candidates' points "
                f"in the region, so InfraNUC cannot be estimated: use larger or more disks "
                "(--radius, --disks)")


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
