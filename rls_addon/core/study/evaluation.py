"""A placement study judged by detection (``rls study --evaluate FRAMES``): every
candidate, and the sets the study reports, scored by the AP of RLS's roadside detector
on the scene's traffic in the InfraLOB, beside InfraD, InfraNUC and visibility; and how
well each of those metrics predicts the AP across the placements.

Per evaluation frame the traffic's ground truth is taken from the scene (``frame_truth``:
the box of each vehicle, pedestrian and cyclist, as ``output.ground_truth`` boxes them:
its mesh's box in its own axes, scale applied). Per candidate (``evaluate_candidate``)
the frames' scans (with the traffic) give the detector's background, learned from those
frames, each frame's foreground, and each object's returns (ghosts left out). A
placement of one or more candidates (``placement_score``) fuses its members' detectors
and foregrounds (early fusion: ``detector.detect`` of their views) and is scored by
``evaluate.scoring.score`` against one ground truth for every placement: a box counts
when its centre is in the region and the study's candidates together put at least
``min_points`` returns on it (``reference_points``). A placement is not let off the
objects it cannot see: a vehicle hidden from it behind a truck is a miss, not a
don't-care, so its AP drops as its visibility does. The headline number is the vehicle
AP_R40 at BEV IoU 0.5 (``HEADLINE``); the whole record is kept."""

import math
import time
from dataclasses import dataclass

import numpy as np

from ..evaluate.detections import CLASS_IDS, Boxes
from ..evaluate.detector.priors import scene_types
from ..evaluate.ground_truth_files import GroundTruth
from ..evaluate.scoring import score
from ..output.ground_truth import box_frame

HEADLINE = ("vehicle", "bev", "0.5", "ap_r40")
IOU_THRESHOLDS = (0.3, 0.5, 0.7)


@dataclass
class FrameTruth:
    """The traffic of one evaluation frame: world ``Boxes`` (score 1) and the instance
    id of each box's object."""

    frame: int
    boxes: Boxes
    instance: np.ndarray


def frame_truth(frame, instances, objects):
    """``FrameTruth`` of the evaluated classes among ``instances`` (``scene.instances``,
    meshes in their own frames) with their ``objects`` table."""
    rows, labels, ids = [], [], []
    for inst, obj in zip(instances, objects):
        if inst.label not in CLASS_IDS or not len(inst.vertices):
            continue
        if not (np.linalg.norm(np.asarray(inst.matrix, np.float64)[:3, :3], axis=0) > 0).all():
            continue  # a flattened object has no box
        pose, size = box_frame(inst.matrix, inst.vertices.min(0), inst.vertices.max(0))
        rows.append([*pose[:3, 3], *size, math.atan2(pose[1, 0], pose[0, 0])])
        labels.append(inst.label)
        ids.append(obj.instance)
    box = np.asarray(rows, np.float64).reshape(-1, 7)
    return FrameTruth(int(frame), Boxes(np.full(len(box), int(frame)), box, labels, 1.0),
                      np.asarray(ids, np.int64))


@dataclass
class CandidateEvaluation:
    """What the evaluation keeps of one candidate (sent back by a study's workers): its
    detector (the background it learned), each frame's foreground and, per frame, the
    returns on each ground-truth object (aligned with that frame's ``FrameTruth``)."""

    name: str
    pose: np.ndarray
    learned: object    # what the detector learned of it (its background)
    views: dict        # frame -> the detector's view of its frame (the foreground)
    points: dict       # frame -> (N,) returns on each of the frame's ground-truth boxes
    detect_s: float = 0.0


def truth_types(truths):
    """The scene's types of road users (``priors.scene_types``) among the evaluation
    frames' ground truth ({frame: FrameTruth}), or None without any."""
    if not truths:
        return None
    parts = list(truths.values())
    labels = np.concatenate([t.boxes.label for t in parts])
    if not len(labels):
        return None
    return scene_types(labels, np.concatenate([t.instance for t in parts]),
                       np.concatenate([t.boxes.box[:, 3:6] for t in parts]))


def evaluate_candidate(detector, name, pose, frame_points, truths, sweeps=None):
    """``CandidateEvaluation`` of candidate ``name`` at ``pose`` (4x4, still) from its
    scans ``frame_points`` {frame: (world xyz (N, 3), instance (N,), ghost (N,))} and
    the frames' ``truths`` {frame: FrameTruth}, by ``detector`` (the protocol). Its
    background is learned from ``sweeps`` (world xyz arrays: the scene without road
    users), or from the frames themselves when None."""
    to_sensor = np.linalg.inv(pose)

    def local(xyz):
        return xyz @ to_sensor[:3, :3].T + to_sensor[:3, 3]

    frames = sorted(frame_points)
    if sweeps is None:
        sweeps = [frame_points[f][0] for f in frames]
    learned = detector.learn(name, [local(xyz) for xyz in sweeps], pose)
    t = time.perf_counter()
    views = {f: detector.view(learned, local(frame_points[f][0]), pose) for f in frames}
    detect_s = (time.perf_counter() - t) / max(len(frames), 1)
    points = {}
    for f in frames:
        _, instance, ghost = frame_points[f]
        ids = truths[f].instance
        seen = np.asarray(instance)[np.asarray(ghost) == 0]
        order = np.argsort(ids, kind="stable")
        at = np.searchsorted(ids[order], seen)
        at = np.clip(at, 0, max(len(ids) - 1, 0))
        hit = len(ids) > 0
        counts = np.zeros(len(ids), np.int64)
        if hit:
            on = ids[order][at] == seen
            np.add.at(counts, order[at[on]], 1)
        points[f] = counts
    return CandidateEvaluation(name, np.asarray(pose, np.float64), learned, views, points,
                               detect_s)


def reference_points(evaluations, truths):
    """{frame: (N,) returns on each ground-truth box summed over every candidate}: what
    decides whether a box counts, the same for every placement."""
    return {f: np.sum([e.points[f] for e in evaluations], axis=0).astype(np.int64)
            if evaluations else np.zeros(len(truths[f].instance), np.int64) for f in truths}


def placement_score(detector, members, truths, polygon, min_points, reference,
                    iou_thresholds=IOU_THRESHOLDS):
    """``scoring.score``'s record of the placement of ``members`` (CandidateEvaluation s):
    each frame's views of the members fused by ``detector``, scored against the boxes
    that ``reference`` ({frame: returns per box}, ``reference_points``) counts."""
    frames = sorted(truths)
    found = [detector.detect([(m.learned, m.views[f]) for m in members], f) for f in frames]
    boxes = Boxes.concat([Boxes(truths[f].boxes.frame, truths[f].boxes.box,
                                truths[f].boxes.label, 1.0, reference[f]) for f in frames])
    instance = np.concatenate([truths[f].instance for f in frames]) if frames \
        else np.zeros(0, np.int64)
    truth = GroundTruth(boxes, frames, {f: members[0].pose for f in frames},
                        np.full(len(boxes), np.nan), instance, members[0].name)
    return score(truth, Boxes.concat(found), region=polygon, min_points=min_points,
                 iou_thresholds=iou_thresholds, kitti=False)


def headline(record):
    """The vehicle AP_R40 at BEV IoU 0.5 of a ``placement_score`` record (None: no
    vehicle counted in the region)."""
    cls, kind, thr, key = HEADLINE
    try:
        return record["classes"][cls]["all"][kind][thr][key]
    except KeyError:
        return None


@dataclass
class StudyEvaluation:
    """The study's placements judged by detection.

    candidates   per candidate: its headline AP (None: nothing counted) and record
    sets         {members tuple: (headline AP, record)} of the sets the study reports:
                 each k's Pareto front and best set, and the best set by visibility
    best         {k: members} of the best set by AP among those of k members
    correlation  {metric name: correlation.correlation record} of AP with InfraD,
                 InfraNUC and each visibility share, over every placement scored
    placements   the rows the correlation ran over: name, members, AP and metrics
    frames, min_points, detect_ms (the detector's foreground per frame and candidate)
    detector     its name; background: what it learned (``background_record``)"""

    frames: list
    min_points: int
    candidates: list
    sets: dict
    best: dict
    correlation: dict
    placements: list
    detect_ms: float
    detector: str = ""
    background: dict = None

    @classmethod
    def of(cls, cfg, scanner, cands, evaluations, searches, visibility):
        from ..evaluate.correlation import correlation

        truths, polygon = scanner.truths, scanner.polygon
        ref = reference_points(evaluations, truths)
        mp = int(cfg.evaluate_min_points)
        det = scanner.detector
        records = [placement_score(det, [e], truths, polygon, mp, ref) for e in evaluations]
        sets = {}
        wanted = []
        for k, s in sorted(searches.items()):
            wanted += [p.members for p in s.front] + [s.best.members]
            if visibility is not None:
                wanted.append(visibility.best[k].members)
        for members in wanted:
            members = tuple(int(i) for i in members)
            if len(members) > 1 and members not in sets:
                rec = placement_score(det, [evaluations[i] for i in members], truths,
                                      polygon, mp, ref)
                sets[members] = (headline(rec), rec)
        scored = {**{(i,): (headline(r), r) for i, r in enumerate(records)}, **sets}
        best = {}
        for k in sorted(searches):
            pool = {m: v for m, v in scored.items() if len(m) == k and v[0] is not None}
            if pool:
                best[k] = max(pool, key=lambda m: (pool[m][0], -sum(m)))
        rows = []
        metric_of = {}
        for members, (ap, _) in sorted(scored.items()):
            p = _metrics(members, cands, searches, visibility)
            rows.append(dict(members=list(members), sensors=[cands[i].name for i in members],
                             ap=ap, **p))
            for name, v in p.items():
                metric_of.setdefault(name, []).append(v)
        aps = [r["ap"] if r["ap"] is not None else np.nan for r in rows]
        corr = {name: correlation(np.array([np.nan if x is None else x for x in v], np.float64),
                                  np.asarray(aps, np.float64))
                for name, v in metric_of.items()}
        ms = 1000.0 * float(np.mean([e.detect_s for e in evaluations])) if evaluations else 0.0
        return cls(sorted(truths), mp, [(headline(r), r) for r in records], sets, best, corr,
                   rows, ms, getattr(det, "name", type(det).__name__),
                   background_record(cfg, scanner.frame))

    def ap_of(self, members):
        """The headline AP of a scored placement (a candidate or a reported set)."""
        members = tuple(members)
        return self.candidates[members[0]][0] if len(members) == 1 else self.sets[members][0]

    def to_dict(self, names):
        def strip(rec):  # the study keeps the summary, not every match
            return {k: v for k, v in rec.items() if k not in ("matches", "frames")}
        return {
            "frames": self.frames, "min_points": self.min_points,
            "headline": "vehicle AP_R40 at BEV IoU 0.5 (fraction of 1)",
            "ground_truth": ("boxes of vehicles, pedestrians and cyclists centred in the "
                             f"region on which the candidates together put >= "
                             f"{self.min_points} returns; the same for every placement"),
            "detector": f"{self.detector}, early fusion over a set",
            "background": self.background,
            "detect_ms_per_frame": round(self.detect_ms, 2),
            "candidates": [{"candidate": names[i], "ap": ap, "result": strip(rec)}
                           for i, (ap, rec) in enumerate(self.candidates)],
            "sets": [{"members": list(m), "sensors": [names[i] for i in m], "ap": ap,
                      "result": strip(rec)} for m, (ap, rec) in sorted(self.sets.items())],
            "best_by_ap": {str(k): {"members": list(m), "sensors": [names[i] for i in m],
                                    "ap": self.ap_of(m)}
                           for k, m in sorted(self.best.items())},
            "placements": self.placements,
            "correlation": self.correlation,
        }


def background_record(cfg, frame):
    """What the study's detector learned its background from (study.json, stderr)."""
    from ..choices import BACKGROUNDS

    kind = cfg.evaluate_background
    if kind == "empty":
        return {"kind": kind, "label": BACKGROUNDS.label(kind),
                "sweeps": int(cfg.background_sweeps), "scene_frame": int(frame),
                "what": f"each candidate's {int(cfg.background_sweeps)} sweeps of the scene "
                        f"at frame {int(frame)} with every road user hidden (vehicles, "
                        "pedestrians, cyclists, parked ones included), the device's noise "
                        "in each: what a deployed unit's background holds"}
    return {"kind": kind, "label": BACKGROUNDS.label(kind),
            "frames": [int(f) for f in cfg.evaluate_frames],
            "what": "learned from the evaluation frames themselves, traffic and all: "
                    "vehicles standing through most of them become background"}


def _metrics(members, cands, searches, visibility):
    """InfraD, InfraNUC and the visibility shares of the placement ``members``."""
    if len(members) == 1:
        c = cands[members[0]]
        out = {"infra_d": c.infra_d, "infra_nuc": c.infra_nuc}
        vis = visibility.candidates[members[0]] if visibility is not None else None
    else:
        k = len(members)
        found = [p for p in searches[k].evaluated if tuple(p.members) == members]
        out = {"infra_d": found[0].infra_d if found else np.nan,
               "infra_nuc": found[0].infra_nuc if found else np.nan}
        vis = visibility.sets[k].get(members) if visibility is not None else None
    if vis is not None:
        out.update({f"share_{t}": v for t, v in vis.shares.items()})
    return {k: (None if v is None or not np.isfinite(v) else float(v)) for k, v in out.items()}
