"""Detection in a placement study, per candidate and per placement (``rls study
--evaluate FRAMES``).

Per evaluation frame the traffic's ground truth is taken from the scene (``frame_truth``:
the box of each vehicle, pedestrian and cyclist, as ``output.ground_truth`` boxes them:
its mesh's box in its own axes, scale applied); the scene's types of road users
(``truth_types``) are the detector's size priors. Per candidate (``evaluate_candidate``)
the detector (the protocol, ``evaluate.detector``) learns its background, from the
candidate's sweeps of the scene with every road user hidden (the default) or from the
frames, and keeps its view of each frame; each object's returns (ghosts left out) are
counted. A placement of one or more candidates (``placement_score``) is detected from
its members' views together (early fusion) and scored by ``evaluate.scoring.score``
against one ground truth for every placement: a box counts when its centre is in the
region and the study's candidates together put at least ``min_points`` returns on it
(``reference_points``). A placement is not let off the objects it cannot see: a vehicle
hidden from it behind a truck is a miss, not a don't-care, so its AP drops as its
visibility does. The headline number is the vehicle AP_R40 at BEV IoU 0.5
(``HEADLINE``); the whole record is kept."""

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
