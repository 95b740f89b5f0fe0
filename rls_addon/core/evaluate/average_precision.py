"""Average precision: the precision-recall curve of a pooled, score-sorted set of
detections, KITTI's 40-recall-point AP and VOC's all-point AP, and the evaluation of a
whole set of detections against ground truth, per class, IoU threshold and overlap kind.

APs are fractions in [0, 1] (KITTI and OpenCOOD print percent). Without counted ground
truth of a class an AP is undefined: ``None`` in the results, with a note, never 0 or 1.
With ground truth but no detections it is 0.

The curve. Detections of all frames (true and false positives; dropped ones left out,
``matching.py``) are sorted by descending score, ties in their given order (a stable
sort), and after the k-th: ``recall = TP_k / n_gt``, ``precision = TP_k / k``. One point
per detection, as OpenCOOD's ``calculate_ap`` (with ``global_sort_detections``; without
it OpenCOOD keeps its frames' order) and VOC; tied scores are not merged.

AP_R40 (``ap_r40``): the mean over the 40 recall points ``r = 1/40, 2/40, ..., 1`` of the
interpolated precision ``max {precision_k : recall_k >= r}`` (0 where recall never reaches
r). This is the definition of Simonelli et al. 2019 (Disentangling Monocular 3D Object
Detection) that KITTI adopted. KITTI's Python evaluation as OpenPCDet ships it
(open-mmlab/OpenPCDet, pcdet/datasets/kitti/kitti_object_eval_python/eval.py) samples it
differently: ``get_thresholds`` walks the scores of the true positives in descending
order and keeps, for each target recall 0, 1/40, 2/40, ... in turn, the score of the true
positive whose recall ``(i + 1) / n_gt`` is nearest the target (at most one target per
true positive, at most 41 thresholds); ``eval_class`` re-matches at each threshold
(detections scoring below it left out), takes ``precision = tp / (tp + fp)``, replaces
each by the maximum over the lower thresholds after it, and ``get_mAP_R40`` sums entries
1 to 40 (not entry 0, the first true positive) and divides by 40; entries without a
threshold are 0. Ours differs where theirs is an approximation: (1) a recall point takes
the precision at recall >= r exactly, not at the true positive nearest r (which may lie
just below r); (2) with fewer than 40 counted boxes KITTI's walk runs out of true
positives before it runs out of targets and leaves the remaining points at 0 (two boxes
both found, nothing false: KITTI 0.025, ours 1.0); (3) KITTI matches box by box (each
ground-truth box takes its best-overlapping detection) at ``IoU > threshold``, we match
greedily by score at ``IoU >= threshold`` (``matching.py``). With many more boxes than
40 the two come close but need not agree: 100 detections of 80 boxes, 63 of them true,
gave 0.594 by KITTI's sampling and 0.578 by ours.

AP_VOC (``ap_voc``): all-point VOC 2010 AP as OpenCOOD computes it (DerrickXuNu/OpenCOOD,
opencood/utils/eval_utils.py, ``voc_ap`` at main 31ba160): recall is given a 0 in front
and a 1 at the end, precision a 0 in front and a 0 at the end; each precision is replaced
by the maximum of itself and all after it (the envelope); AP is the sum, over the
positions i >= 1 where recall changes, of ``(recall_i - recall_{i-1}) * precision_i``.
Recall beyond the last detection thus adds nothing. (An unmerged pull-request copy of
that file weights by recall instead of precision; main weights by precision.)"""

import math

import numpy as np

from ..errors import InputError
from ..labels import DEFAULT_LABELS
from .detections import CLASS_IDS, class_id
from .kitti_official import class_frames, kitti_r40
from .matching import FP, IGNORED, TP, as_flags, check_threshold, match, pair_overlaps
from .overlap import IOU_KINDS

RECALL_POINTS = 40
DEFAULT_THRESHOLDS = (0.3, 0.5, 0.7)
UNDEFINED = "no counted ground truth of this class here: AP undefined"


def precision_recall(score, status, n_gt):
    """The precision-recall curve of pooled detections: ``score`` (D,) and ``status``
    (D,) (``matching.TP``, ``FP``, or ``IGNORED``, which are left out); ``n_gt`` counted
    ground-truth boxes. Returns (recall, precision, score), each (K,) float64 in
    descending score, ties in their given order; recall is NaN without ground truth."""
    score = np.asarray(score, np.float64).reshape(-1)
    status = np.asarray(status).reshape(-1)
    if score.shape != status.shape:
        raise InputError(f"precision_recall: {len(score)} scores but {len(status)} "
                         "statuses")
    keep = (status == TP) | (status == FP)
    score, hit = score[keep], status[keep] == TP
    order = np.argsort(-score, kind="stable")
    score, hit = score[order], hit[order]
    tp = np.cumsum(hit)
    precision = tp / np.arange(1, len(tp) + 1)
    recall = tp / n_gt if n_gt > 0 else np.full(len(tp), np.nan)
    return recall, precision, score


def ap_r40(recall, precision):
    """KITTI's 40-recall-point AP (see the module docstring) of a curve from
    ``precision_recall``: recall (K,) non-decreasing, precision (K,)."""
    recall = np.asarray(recall, np.float64)
    precision = np.asarray(precision, np.float64)
    if not len(recall):
        return 0.0
    # Best precision at or after each point; recall = TP / n_gt and r = k / 40 are each
    # one rounded division, so ">=" between them is exact.
    envelope = np.maximum.accumulate(precision[::-1])[::-1]
    points = np.arange(1, RECALL_POINTS + 1) / RECALL_POINTS
    first = np.searchsorted(recall, points, side="left")
    reached = first < len(recall)
    values = np.where(reached, envelope[np.minimum(first, len(recall) - 1)], 0.0)
    return float(values.mean())


def ap_voc(recall, precision):
    """All-point VOC AP as OpenCOOD's ``voc_ap`` (see the module docstring) of a curve
    from ``precision_recall``: recall (K,) non-decreasing, precision (K,)."""
    mrec = np.concatenate([[0.0], np.asarray(recall, np.float64), [1.0]])
    mpre = np.concatenate([[0.0], np.asarray(precision, np.float64), [0.0]])
    mpre = np.maximum.accumulate(mpre[::-1])[::-1]
    step = np.diff(mrec)
    changed = step != 0
    return float((step[changed] * mpre[1:][changed]).sum())


def _classes(classes):
    if classes is None:
        return list(CLASS_IDS)
    out = []
    for c in ([classes] if isinstance(classes, (str, int, np.integer)) else classes):
        cid = class_id(c) if isinstance(c, str) else int(c)
        if cid not in CLASS_IDS:
            known = ", ".join(f"{DEFAULT_LABELS[i]} ({i})" for i in CLASS_IDS)
            raise InputError(f"class {c!r} is not evaluated: RLS evaluates {known}")
        if cid not in out:
            out.append(cid)
    return out


def distance_bins_of(distance_bins):
    """[(low, high)] metres from the bin edges (increasing, from 0 m or more), or []
    without bins; one ``InputError`` for edges that are not."""
    if distance_bins is None:
        return []
    try:
        edges = [float(e) for e in distance_bins]
    except (TypeError, ValueError):
        raise InputError(f"distance bins {distance_bins!r}: give the bin edges in metres, "
                         "e.g. 0, 30, 50, inf") from None
    if len(edges) < 2 or any(math.isnan(e) for e in edges) or edges[0] < 0 or \
            any(b <= a for a, b in zip(edges, edges[1:])):
        raise InputError(f"distance bins {edges!r}: give at least two increasing edges "
                         "from 0 m or more, e.g. 0, 30, 50, inf")
    return list(zip(edges, edges[1:]))


def in_bin(distance, low, high):
    """(N,) bool: ``distance`` (m) lies in the bin ``[low, high)``: a box exactly on an
    edge belongs to the bin that starts there. The one place the rule is written (the
    evaluation's bins here and ``scoring``'s, from the nearest sensor, both use it)."""
    distance = np.asarray(distance, np.float64)
    return (distance >= low) & (distance < high)


def _bins(distance_bins, sensor_xy):
    """``distance_bins_of``, with the sensor's position the distances are measured from."""
    bins = distance_bins_of(distance_bins)
    if bins and sensor_xy is None:
        raise InputError("distance bins need the sensor's position (sensor_xy, world x "
                         "and y in metres) to measure distances from")
    return bins


def _sensor(sensor_xy):
    if sensor_xy is None:
        return None
    xy = np.asarray(sensor_xy, np.float64).reshape(-1)
    if xy.shape != (2,) or not np.isfinite(xy).all():
        raise InputError(f"sensor_xy {sensor_xy!r} must be the sensor's world x and y "
                         "in metres")
    return xy


def _record(score, status, of_class, det_in, n_gt, gt_ignored, kitti=None):
    """One class's result: its detections' curve and APs, and the counts. Dropped
    detections are counted where they are centred (``det_in``, the bin). ``kitti``:
    KITTI's official AP_R40 of the class (``kitti_official``), when worked out."""
    status = status[of_class]
    recall, precision, kept = precision_recall(score[of_class], status, n_gt)
    tp = int((status == TP).sum())
    fp = int((status == FP).sum())
    out = {
        "ap_r40": ap_r40(recall, precision) if n_gt else None,
        "ap_r40_kitti": kitti if n_gt else None,
        "ap_voc": ap_voc(recall, precision) if n_gt else None,
        "tp": tp, "fp": fp, "gt": int(n_gt), "missed": int(n_gt) - tp,
        "ignored": int((status[det_in[of_class]] == IGNORED).sum()),
        "gt_ignored": int(gt_ignored),
        "recall": [float(r) for r in recall] if n_gt else [],
        "precision": [float(p) for p in precision],
        "score": [float(s) for s in kept],
    }
    if not n_gt:
        out["note"] = UNDEFINED
    return out


def _threshold_key(threshold):
    return f"{threshold:g}"


def evaluate(ground_truth, detections, gt_ignore=None, det_ignore=None,
             iou_thresholds=DEFAULT_THRESHOLDS, kinds=IOU_KINDS, classes=None,
             distance_bins=None, sensor_xy=None, kitti=True):
    """Score ``detections`` against ``ground_truth`` (both ``Boxes``, world frame).

    ``gt_ignore`` (G,) and ``det_ignore`` (D,) flag don't-care boxes (``matching.py``).
    For each class (default vehicle, pedestrian, cyclist), overlap kind ('bev', '3d')
    and IoU threshold (default 0.3, 0.5, 0.7) detections are matched frame by frame and
    pooled over frames. ``distance_bins`` (edges in metres, e.g. ``(0, 30, 50, inf)``)
    adds the same per range of XY distance from ``sensor_xy`` to the box centre: in a
    bin, ground truth centred outside it is ignored and detections centred outside it
    are don't-care detections (dropped unless they match a counted box in the bin).
    With ``kitti`` each record also holds KITTI's official AP_R40 as OpenPCDet's code
    computes it (``kitti_official``; None without counted ground truth).

    Returns a JSON-ready dict::

        {"iou_thresholds": [...], "kinds": [...], "distance_bins": [[lo, hi|None], ...],
         "classes": {name: {"label": id,
                            "all": {kind: {threshold: record}},
                            "bins": [{"range_m": [lo, hi|None], kind: {...}}, ...]}}}

    where a threshold key is its ``%g`` text ('0.5') and a record is ``{"ap_r40",
    "ap_voc" (None without counted ground truth, with a "note"), "tp", "fp", "gt"
    (counted), "missed", "ignored" (dropped detections centred in the range),
    "gt_ignored" (flagged ground truth centred in the range), "recall", "precision",
    "score" (the curve, one point per kept detection)}``. A range's true positives
    include detections centred just outside it that took one of its boxes."""
    ground_truth = ground_truth.validate("ground truth")
    detections = detections.validate("detections")
    n_gt, n_det = len(ground_truth), len(detections)
    gt_ignore = as_flags(gt_ignore, n_gt, "gt_ignore")
    det_ignore = as_flags(det_ignore, n_det, "det_ignore")
    if np.ndim(iou_thresholds) == 0:
        iou_thresholds = [iou_thresholds]
    thresholds = list(dict.fromkeys(check_threshold(t) for t in iou_thresholds))
    if not thresholds:
        raise InputError("no IoU thresholds given")
    kinds = [kinds] if isinstance(kinds, str) else list(kinds)
    for kind in kinds:
        if kind not in IOU_KINDS:
            raise InputError(f"unknown overlap kind '{kind}': choose one of "
                             + ", ".join(IOU_KINDS))
    class_ids = _classes(classes)
    bins = _bins(distance_bins, sensor_xy)
    sensor = _sensor(sensor_xy)
    # Only the evaluated classes take part (other labels are neither matched nor false).
    gt_rows = np.flatnonzero(np.isin(ground_truth.label, class_ids))
    det_rows = np.flatnonzero(np.isin(detections.label, class_ids))
    gt, det = ground_truth.take(gt_rows), detections.take(det_rows)
    gt_ignore, det_ignore = gt_ignore[gt_rows], det_ignore[det_rows]

    everything_gt, everything_det = np.ones(len(gt), bool), np.ones(len(det), bool)
    scopes = [(None, everything_gt, everything_det)]
    if bins:
        gt_range = np.hypot(gt.box[:, 0] - sensor[0], gt.box[:, 1] - sensor[1])
        det_range = np.hypot(det.box[:, 0] - sensor[0], det.box[:, 1] - sensor[1])
        for low, high in bins:
            gt_in, det_in = in_bin(gt_range, low, high), in_bin(det_range, low, high)
            scopes.append(((low, high), gt_in, det_in))

    results = {c: {"label": int(c), "all": {}, "bins": []} for c in class_ids}
    for c in class_ids:
        for low, high in bins:
            results[c]["bins"].append(
                {"range_m": [low, None if math.isinf(high) else high]})
    for kind in kinds:
        overlaps = pair_overlaps(det, gt, kind)
        for s, (scope, gt_in, det_in) in enumerate(scopes):
            g_ignore, d_ignore = gt_ignore | ~gt_in, det_ignore | ~det_in
            frames = {c: class_frames(overlaps, det, gt, g_ignore, d_ignore, c)
                      for c in class_ids} if kitti else {}
            for threshold in thresholds:
                m = match(det, gt, threshold, kind, g_ignore, d_ignore, overlaps)
                for c in class_ids:
                    gc = gt.label == c
                    record = _record(det.score, m.status, det.label == c, det_in,
                                     int((gc & ~g_ignore).sum()),
                                     int((gc & gt_in & gt_ignore).sum()),
                                     kitti_r40(frames[c], threshold) if kitti else None)
                    place = results[c]["all"] if scope is None \
                        else results[c]["bins"][s - 1]
                    place.setdefault(kind, {})[_threshold_key(threshold)] = record
    return {
        "iou_thresholds": thresholds,
        "kinds": kinds,
        "distance_bins": [[lo, None if math.isinf(hi) else hi] for lo, hi in bins],
        "sensor_xy": None if sensor is None else [float(v) for v in sensor],
        "classes": {DEFAULT_LABELS[c]: results[c] for c in class_ids},
    }

