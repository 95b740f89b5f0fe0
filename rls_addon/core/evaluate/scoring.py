"""Scoring detections against RLS's ground truth in a region of interest: what
``rls evaluate`` runs.

What counts. A ground-truth box counts when its centre lies inside the region (a
polygon in world x-y, e.g. the InfraLOB; None: everywhere) and it has at least
``min_points`` returns (default 5, as TUMTraf evaluates; ``points`` of the sidecar's
``objects``, summed over the sensors). Every other box is don't-care (KITTI's ignored
boxes, ``matching.py``): never missed, and a detection that takes it is neither a hit
nor a false positive. Detections centred outside the region are dropped unless they
take a counted box (``det_ignore``): a false alarm outside the region is forgiven, a
found object is not.

Several LiDARs. Each ``GroundTruth`` (one per sensor) lists every box of its frames,
seen or not, with the points that sensor put on it. They are merged by (frame,
instance): one box per object (the box of the sensor with the most points on it; the
first given on a tie), its points the sum of all sensors', so a set of LiDARs is scored
as one (early fusion's ground truth). The sensors must cover the same frames.

Distances. ``distance_bins`` (edges in metres) score each range of horizontal distance
from a box centre to the frame's sensor at its sweep start (with several sensors: the
nearest), in the manner of ``average_precision.evaluate``: in a bin, boxes centred
outside it are don't-care and detections centred outside it are dropped unless they
take one of its counted boxes.

Only the frames the detections cover are scored (OpenPCDet's ``result.pkl`` holds its
test split only); a notice says how many of the ground truth's frames that is.

``score`` returns a JSON-ready dict: ``average_precision.evaluate``'s result (APs both
ways, curves, counts per class, overlap kind and threshold, and per distance bin),
with the ground truth and detections described, counts per frame and sensor, and
every detection's best overlap and status (``matches``)."""

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, RegionError
from ..labels import DEFAULT_LABELS
from ..metrics.polygon import as_polygon, points_in_polygon, shoelace_area
from .average_precision import DEFAULT_THRESHOLDS, distance_bins_of, evaluate, in_bin
from .detections import CLASS_IDS, Boxes, class_id
from .ground_truth_files import GroundTruth
from .matching import FP, IGNORED, TP, check_threshold, match, pair_overlaps
from .overlap import IOU_KINDS

DEFAULT_MIN_POINTS = 5

CONVENTIONS = {
    "ap_r40": "KITTI's AP at 40 recall points (Simonelli et al. 2019, 'Disentangling "
              "Monocular 3D Object Detection'; KITTI's benchmark since 2019): the mean "
              "over r = 1/40 ... 1 of the best precision at recall >= r",
    "ap_r40_kitti": "KITTI's official AP_R40 as OpenPCDet's kitti_object_eval_python "
                    "computes it (eval.py): box-by-box matching at IoU > threshold, the "
                    "curve sampled at the true positives' scores, recall points past the "
                    "last one left 0 (fewer than 40 counted boxes leave some at 0)",
    "ap_voc": "VOC 2010 all-point AP as OpenCOOD's voc_ap computes it "
              "(opencood/utils/eval_utils.py): the area under the precision envelope",
    "matching": "greedy by descending score, frame by frame and class by class, at "
                "IoU >= threshold (as OpenCOOD); KITTI asks IoU > threshold",
    "fractions": "APs are fractions in [0, 1] (KITTI and OpenCOOD print percent); null "
                 "where a class has no counted ground truth",
}
STATUS = {TP: "tp", FP: "fp", IGNORED: "ignored"}


@dataclass
class MergedTruth:
    """The ground truth of one or more sensors as one: a box per (frame, object)."""
    boxes: Boxes              # world boxes, points summed over the sensors
    instance: np.ndarray      # (G,) int64
    points_by_sensor: np.ndarray  # (G, S) float64: each sensor's points on each box
    frames: list
    sensors: list             # S names
    positions: dict = field(default_factory=dict)  # frame -> (S, 3) sensor positions
    speed: np.ndarray = None  # (G,) horizontal speed of each box, m/s (NaN: unknown)

    def __post_init__(self):
        if self.speed is None:
            self.speed = np.full(len(self.boxes), np.nan)

    def distance(self, boxes):
        """(N,) horizontal distance (m) from each box centre to the nearest sensor of
        its frame (at the sweep start)."""
        if not len(boxes):
            return np.zeros(0)
        index = {f: k for k, f in enumerate(self.frames)}
        where = np.array([index[int(f)] for f in boxes.frame])
        xy = np.stack([self.positions[f][:, :2] for f in self.frames])  # (F, S, 2)
        d = boxes.box[:, None, :2] - xy[where]
        return np.hypot(d[..., 0], d[..., 1]).min(axis=1)


def frames_text(frames, most=12):
    """'1-3, 7, 9-10' for a list of frame numbers (runs joined), at most ``most``
    pieces."""
    frames = sorted(set(int(f) for f in frames))
    runs = []
    for f in frames:
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    parts = [f"{a}" if a == b else f"{a}-{b}" for a, b in runs]
    if len(parts) > most:
        parts = parts[:most] + [f"... ({len(frames)} frames)"]
    return ", ".join(parts) or "none"


def _sensor_names(truths):
    names = [t.sensor or f"sensor {k + 1}" for k, t in enumerate(truths)]
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"the ground truth of sensor {n!r} is given twice: give each "
                             "sensor's ground truth once")
        seen.add(n)
    return names


def merge_ground_truth(truth):
    """``MergedTruth`` of a ``GroundTruth`` or a list of them (one per sensor); see the
    module docstring."""
    truths = [truth] if isinstance(truth, GroundTruth) else list(truth or [])
    if not truths:
        raise InputError("no ground truth given")
    names = _sensor_names(truths)
    frames = sorted(truths[0].frames)
    for name, t in zip(names[1:], truths[1:]):
        if sorted(t.frames) != frames:
            raise InputError(
                f"the sensors' ground truth covers different frames: {names[0]} has "
                f"{frames_text(frames)}, {name} has {frames_text(t.frames)}; a set of "
                "LiDARs is scored as one: scan the same frames with every sensor")
    positions = {f: np.array([t.sensor_pose[f][:3, 3] for t in truths], np.float64)
                 for f in frames}
    if len(truths) == 1:
        t = truths[0]
        return MergedTruth(t.boxes, np.asarray(t.instance, np.int64),
                           t.boxes.points[:, None].copy(), frames, names, positions,
                           np.asarray(t.speed, np.float64))
    for name, t in zip(names, truths):
        if len(t.boxes) and (np.asarray(t.instance) == 0).any():
            raise InputError(f"the ground truth of {name} has boxes without an instance id; "
                             "boxes of several sensors are merged by instance: write the "
                             "dataset again with this version of RLS")
    every = Boxes.concat([t.boxes for t in truths])
    speed = np.concatenate([np.asarray(t.speed, np.float64) for t in truths])
    instance = np.concatenate([np.asarray(t.instance, np.int64) for t in truths])
    sensor = np.concatenate([np.full(len(t.boxes), k) for k, t in enumerate(truths)])
    if not len(every):
        return MergedTruth(every, instance, np.zeros((0, len(truths))), frames, names,
                           positions)
    keys, inverse = np.unique(np.stack([every.frame, instance], axis=1), axis=0,
                              return_inverse=True)
    inverse = inverse.reshape(-1)
    by_sensor = np.zeros((len(keys), len(truths)))
    np.add.at(by_sensor, (inverse, sensor), every.points)
    # each object's box: the sensor with the most points on it, the first on a tie
    order = np.lexsort((np.arange(len(every)), sensor, -every.points, inverse))
    first = order[np.searchsorted(inverse[order], np.arange(len(keys)))]
    boxes = every.take(first)
    boxes.points = by_sensor.sum(axis=1)
    return MergedTruth(boxes, instance[first], by_sensor, frames, names, positions,
                       speed[first])


def _region(region):
    """(M, 2) polygon or None; ``InputError`` for a degenerate one."""
    if region is None:
        return None
    try:
        return as_polygon(region)
    except RegionError as exc:
        raise InputError(str(exc)) from None


def _classes(classes):
    """RLS label ids of the classes to score (None: vehicle, pedestrian, cyclist)."""
    if classes is None:
        return list(CLASS_IDS)
    if isinstance(classes, str):
        classes = [c for c in classes.split(",") if c.strip()]
    out = []
    for c in classes:
        cid = class_id(c) if isinstance(c, str) else int(c)
        if cid not in CLASS_IDS:
            known = ", ".join(DEFAULT_LABELS[i] for i in CLASS_IDS)
            raise InputError(f"unknown class {c!r}: RLS evaluates {known}")
        if cid not in out:
            out.append(cid)
    if not out:
        raise InputError("no classes given to score")
    return out


def _min_points(min_points):
    if isinstance(min_points, bool) or not isinstance(min_points, (int, np.integer)) \
            or min_points < 0:
        raise InputError(f"min_points {min_points!r} must be a whole number >= 0 (the "
                         "returns a ground-truth box needs to count)")
    return int(min_points)


def _detection_frames(detections, truth_frames):
    """(Boxes, frames the detections cover) of ``Boxes`` or ``readers.DetectionFiles``;
    ``InputError`` for frames the ground truth does not have."""
    boxes = getattr(detections, "boxes", detections)
    if not isinstance(boxes, Boxes):
        raise InputError("detections must be Boxes or DetectionFiles (readers.py)")
    covered = getattr(detections, "frames", None)
    if covered is not None and not len(covered):
        raise InputError("the detections cover no frame (an empty prediction folder?)")
    covered = sorted(set(int(f) for f in (covered if covered is not None else truth_frames))
                     | set(int(f) for f in boxes.frame))
    unknown = sorted(set(covered) - set(truth_frames))
    if unknown:
        raise InputError(f"detections for frames {frames_text(unknown)} that the ground "
                         f"truth does not have (it has frames {frames_text(truth_frames)}); "
                         "were they made on another dataset or frame range?")
    return boxes, covered


def _no_truth_error(gt, in_region, region, min_points, class_ids):
    names = ", ".join(DEFAULT_LABELS[c] for c in class_ids)
    n = len(gt)
    if region is None:
        return InputError(f"no ground-truth box of {names} has >= {min_points} points in "
                          f"the frames scored ({n} boxes, the most points "
                          f"{int(gt.points.max()) if n else 0}); lower --min-points or "
                          "score other frames")
    inside = int(in_region.sum())
    most = int(gt.points[in_region].max()) if inside else 0
    lo, hi = region.min(axis=0), region.max(axis=0)
    return InputError(
        f"no ground-truth box with >= {min_points} points has its centre inside the "
        f"region; of {n} boxes of {names} in the frames scored, {inside} are centred "
        f"inside (the most points {most}) and {n - inside} outside; the region spans "
        f"x {lo[0]:g} to {hi[0]:g}, y {lo[1]:g} to {hi[1]:g} m (world): check that it is "
        "the scene's region, or lower --min-points")


def score(truth, detections, region=None, min_points=DEFAULT_MIN_POINTS, classes=None,
          iou_thresholds=DEFAULT_THRESHOLDS, kinds=IOU_KINDS, distance_bins=None,
          kitti=True):
    """Score ``detections`` (``Boxes`` or ``readers.DetectionFiles``, world frame)
    against ``truth`` (a ``GroundTruth`` or a list of them, one per sensor) in
    ``region`` ((M, 2) world x-y polygon; None: everywhere). See the module docstring.
    ``InputError`` for frames the ground truth lacks, boxes that are no boxes, unknown
    classes, a degenerate region, or no counted ground truth at all. ``kitti``: each
    record also holds KITTI's official AP_R40 (``kitti_official``; off, it is None)."""
    merged = merge_ground_truth(truth)
    poly = _region(region)
    min_points = _min_points(min_points)
    class_ids = _classes(classes)
    bins = distance_bins_of(distance_bins)
    kinds = [kinds] if isinstance(kinds, str) else list(dict.fromkeys(kinds))
    for kind in kinds:
        if kind not in IOU_KINDS:
            raise InputError(f"unknown overlap kind {kind!r}: choose one of "
                             + ", ".join(IOU_KINDS))
    if np.ndim(iou_thresholds) == 0:
        iou_thresholds = [iou_thresholds]
    thresholds = list(dict.fromkeys(check_threshold(t) for t in iou_thresholds))
    if not thresholds or not kinds:
        raise InputError("no IoU thresholds or overlap kinds given")
    det_all, scored = _detection_frames(detections, merged.frames)
    det_all = det_all.validate("detections")
    notices = []
    if len(scored) < len(merged.frames):
        notices.append(f"scored {len(scored)} of the ground truth's {len(merged.frames)} "
                       f"frames: those the detections cover ({frames_text(scored)})")

    # The scored frames and classes only.
    g_rows = np.isin(merged.boxes.frame, scored) & np.isin(merged.boxes.label, class_ids)
    d_rows = np.isin(det_all.label, class_ids)
    gt, det = merged.boxes.take(g_rows), det_all.take(d_rows)
    instance, by_sensor = merged.instance[g_rows], merged.points_by_sensor[g_rows]
    speed = merged.speed[g_rows]
    gt_in = np.ones(len(gt), bool) if poly is None else points_in_polygon(gt.box[:, :2], poly)
    det_in = np.ones(len(det), bool) if poly is None \
        else points_in_polygon(det.box[:, :2], poly)
    enough = gt.points >= min_points
    counted = gt_in & enough
    if not counted.any():
        raise _no_truth_error(gt, gt_in, poly, min_points, class_ids)
    gt_ignore, det_ignore = ~counted, ~det_in

    result = evaluate(gt, det, gt_ignore, det_ignore, thresholds, kinds, class_ids,
                      kitti=kitti)
    result["conventions"] = CONVENTIONS
    gt_range, det_range = merged.distance(gt), merged.distance(det)
    overlaps = {kind: pair_overlaps(det, gt, kind) for kind in kinds}
    _add_bins(result, gt, det, gt_ignore, det_ignore, gt_range, det_range, bins, kinds,
              thresholds, class_ids, overlaps, kitti)
    matchings = {(kind, t): match(det, gt, t, kind, gt_ignore, det_ignore, overlaps[kind])
                 for kind in kinds for t in thresholds}
    _add_motion(result, gt, counted, speed, matchings, class_ids)
    result["distance_bins"] = [[lo, None if math.isinf(hi) else hi] for lo, hi in bins]
    result["distance_from"] = ("horizontal distance from the box centre to the frame's "
                               "sensor at its sweep start (with several sensors: the "
                               "nearest)")
    result["region"] = None if poly is None else {
        "polygon": poly.tolist(), "area_m2": abs(shoelace_area(poly))}
    result["min_points"] = min_points
    result["ground_truth"] = {
        "sensors": merged.sensors, "frames": scored, "boxes": int(len(gt)),
        "counted": int(counted.sum()),
        "ignored_outside_region": int((~gt_in).sum()),
        "ignored_few_points": int((gt_in & ~enough).sum()),
        "not_scored_classes": int((np.isin(merged.boxes.frame, scored) & ~g_rows).sum())}
    result["detections"] = {
        "boxes": int(len(det)), "outside_region": int((~det_in).sum()),
        "not_scored_classes": int(len(det_all) - len(det))}
    result["frames"] = _per_frame(merged, scored, gt, det, counted, by_sensor, matchings,
                                  class_ids, min_points)
    result["matches"] = _matches(gt, det, det_in, det_range, instance, overlaps, matchings)
    result["notices"] = notices
    return result


def _add_bins(result, gt, det, gt_ignore, det_ignore, gt_range, det_range, bins, kinds,
              thresholds, class_ids, overlaps, kitti=True):
    """Each class's ``bins`` as ``evaluate`` gives them, with distances per frame."""
    for name in result["classes"]:
        result["classes"][name]["bins"] = []
    for low, high in bins:
        g_in, d_in = in_bin(gt_range, low, high), in_bin(det_range, low, high)
        g_ignore, d_ignore = gt_ignore | ~g_in, det_ignore | ~d_in
        part = evaluate(gt, det, g_ignore, d_ignore, thresholds, kinds, class_ids,
                        kitti=kitti)
        status = {(kind, t): match(det, gt, t, kind, g_ignore, d_ignore,
                                   overlaps[kind]).status
                  for kind in kinds for t in thresholds}
        for c in class_ids:
            name = DEFAULT_LABELS[c]
            records = part["classes"][name]["all"]
            for (kind, t), st in status.items():
                rec = records[kind][f"{t:g}"]
                # counted where they are centred: dropped detections and flagged ground
                # truth in this range
                rec["ignored"] = int(((st == IGNORED) & d_in & (det.label == c)).sum())
                rec["gt_ignored"] = int((gt_ignore & g_in & (gt.label == c)).sum())
            entry = {"range_m": [low, None if math.isinf(high) else high]}
            entry.update(records)
            result["classes"][name]["bins"].append(entry)


STANDING_MPS = 0.1  # SUMO's halting speed (SUMO_const_haltingSpeed, utils/common/StdDefs.h)


def _add_motion(result, gt, counted, speed, matchings, class_ids):
    """Per class, kind and threshold: the counted boxes standing (horizontal speed below
    ``STANDING_MPS``) and moving, each with how many were found (``by_motion``); boxes
    whose speed the ground truth does not give are ``unknown``."""
    state = np.where(np.isnan(speed), "unknown",
                     np.where(speed < STANDING_MPS, "standing", "moving"))
    for c in class_ids:
        name = DEFAULT_LABELS[c]
        mine = counted & (gt.label == c)
        for (kind, t), m in matchings.items():
            by = {}
            for what in ("standing", "moving", "unknown"):
                rows = mine & (state == what)
                n, hit = int(rows.sum()), int((rows & (m.gt_det >= 0)).sum())
                if n or what != "unknown":
                    by[what] = {"gt": n, "tp": hit, "missed": n - hit,
                                "recall": hit / n if n else None}
            result["classes"][name]["all"][kind][f"{t:g}"]["by_motion"] = by


def _per_frame(merged, scored, gt, det, counted, by_sensor, matchings, class_ids,
               min_points):
    """Counts per frame: ground truth, and per overlap kind and threshold true and false
    positives, dropped detections and misses, for all classes and each; per sensor its
    position and the counted boxes it alone put ``min_points`` on."""
    n = len(scored)
    fg = np.searchsorted(scored, gt.frame)
    fd = np.searchsorted(scored, det.frame)

    def per_frame(where, mask):
        return np.bincount(where[mask], minlength=n).tolist()

    alone = [per_frame(fg, counted & (by_sensor[:, k] >= min_points))
             for k in range(len(merged.sensors))]
    tables = {}
    for c in [None] + class_ids:
        gc = np.ones(len(gt), bool) if c is None else gt.label == c
        dc = np.ones(len(det), bool) if c is None else det.label == c
        table = {"gt": per_frame(fg, gc & counted), "gt_ignored": per_frame(fg, gc & ~counted),
                 "detections": per_frame(fd, dc)}
        for (kind, t), m in matchings.items():
            table[(kind, f"{t:g}")] = {
                "tp": per_frame(fd, dc & (m.status == TP)),
                "fp": per_frame(fd, dc & (m.status == FP)),
                "ignored": per_frame(fd, dc & (m.status == IGNORED)),
                "missed": per_frame(fg, gc & counted & (m.gt_det < 0))}
        tables[c] = table
    out = []
    for i, f in enumerate(scored):
        entry = {"frame": int(f), "sensors": {
            s: {"position": [float(v) for v in merged.positions[f][k]],
                "counted_alone": alone[k][i]} for k, s in enumerate(merged.sensors)}}
        for c, table in tables.items():
            rec = {}
            for key, value in table.items():
                if isinstance(key, tuple):
                    rec.setdefault(key[0], {})[key[1]] = {x: v[i] for x, v in value.items()}
                else:
                    rec[key] = value[i]
            if c is None:
                entry["all"] = rec
            else:
                entry.setdefault("classes", {})[DEFAULT_LABELS[c]] = rec
        out.append(entry)
    return out


def _matches(gt, det, det_in, det_range, instance, overlaps, matchings):
    """Per detection: frame, class, score, box, whether it is centred in the region, its
    distance, per kind its best IoU with any ground truth of its frame and class (and
    that box's instance), and its status at each kind and threshold."""
    best = {}
    for kind, ov in overlaps.items():
        iou = np.zeros(len(det))
        inst = np.full(len(det), -1, np.int64)
        if len(ov.iou):
            order = np.lexsort((ov.gt, -ov.iou, ov.det))  # best first per detection
            first = np.unique(ov.det[order], return_index=True)[1]
            pick = order[first]
            iou[ov.det[pick]] = ov.iou[pick]
            inst[ov.det[pick]] = np.where(ov.iou[pick] > 0, instance[ov.gt[pick]], -1)
        best[kind] = (iou, inst)
    out = []
    for i in range(len(det)):
        status = {}
        for (kind, t), m in matchings.items():
            status.setdefault(kind, {})[f"{t:g}"] = STATUS[int(m.status[i])]
        out.append({
            "frame": int(det.frame[i]), "class": DEFAULT_LABELS[int(det.label[i])],
            "score": float(det.score[i]), "box": [float(v) for v in det.box[i]],
            "in_region": bool(det_in[i]), "distance_m": float(det_range[i]),
            "best": {kind: {"iou": float(best[kind][0][i]),
                            "instance": None if best[kind][1][i] < 0
                            else int(best[kind][1][i])} for kind in overlaps},
            "status": status})
    return out


__all__ = ["CONVENTIONS", "DEFAULT_MIN_POINTS", "MergedTruth", "STANDING_MPS", "frames_text",
           "merge_ground_truth", "score"]
