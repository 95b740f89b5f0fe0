"""KITTI's official AP_R40 as OpenPCDet's ``kitti_object_eval_python`` computes it
(open-mmlab/OpenPCDet, pcdet/datasets/kitti/kitti_object_eval_python/eval.py at
8cacccec, 2024-04-17: ``compute_statistics_jit``, ``get_thresholds``, ``eval_class``,
``get_mAP_R40``), beside the textbook R40 of ``average_precision.ap_r40``. Users compare
against that code's figures, which differ from the textbook definition by its
conventions:

1. Matching, per frame, goes box by box in the ground truth's order (not by score): a
   counted box takes, of the detections not yet taken whose IoU with it is *above* the
   threshold (``>``, where RLS's matching asks ``>=``), the one of highest score when
   the thresholds are collected, and the one it overlaps most when the curve is
   counted; a detection flagged ignored is taken only when no other qualifies, and then
   neither it nor the box counts. A don't-care box takes a detection the same way,
   which then does not count either.
2. The curve is sampled at thresholds: the scores of the true positives found at
   threshold 0, sorted, walked with the target recalls 0, 1/40, ..., 1 in turn, each
   target taking the true positive whose recall ``(i + 1) / n`` is nearest it (the last
   true positive is always one). At each threshold the matching is run again with the
   detections scoring below it left out, and precision is ``tp / (tp + fp)``.
3. Each precision is replaced by the largest at that threshold or a higher recall, and
   AP_R40 is the sum of entries 1 to 40 divided by 40; entries past the last threshold
   stay 0, so with fewer than 40 counted boxes some recall points are 0 whatever was
   found (two boxes both found, nothing false: 0.05 here and 2/40 there, 1.0 in the
   textbook).

RLS maps its don't-care ground truth (outside the region, too few points) to KITTI's
ignored boxes (``ignored_gt = 1``) and its detections centred outside the region to
KITTI's ignored detections (``ignored_det = 1``); other classes take no part
(``-1``). Nothing of KITTI's image-plane difficulty applies (no camera): the flags are
RLS's. The IoU is RLS's exact one in float64 (OpenPCDet's is float32 on the GPU): the
figures agree to 1e-4 on boxes whose IoUs are not within float32 rounding of a
threshold (``tests/core/evaluate/test_kitti_official.py`` against figures from
OpenPCDet's own code, ``tests/fixtures/kitti_official/``)."""

import numpy as np

N_SAMPLE_PTS = 41
_NO_DETECTION = -10000000.0


def get_thresholds(scores, num_gt, num_sample_pts=N_SAMPLE_PTS):
    """The score thresholds the curve is sampled at (see the module docstring, 2)."""
    scores = np.sort(np.asarray(scores, np.float64))[::-1]
    current, out = 0.0, []
    for i, score in enumerate(scores):
        l_recall = (i + 1) / num_gt
        r_recall = (i + 2) / num_gt if i < len(scores) - 1 else l_recall
        if (r_recall - current) < (current - l_recall) and i < len(scores) - 1:
            continue
        out.append(score)
        current += 1 / (num_sample_pts - 1.0)
    return out


def _statistics(overlap, ignored_gt, ignored_det, score, min_overlap, thresh, compute_fp):
    """(tp, fp, scores of the true positives) of one frame (``compute_statistics_jit``
    for bird's-eye and 3D boxes: no don't-care areas in the image). ``overlap`` (D, G)."""
    det_size, gt_size = overlap.shape
    assigned = [False] * det_size
    below = [compute_fp and score[j] < thresh for j in range(det_size)]
    tp = fp = 0
    found = []
    for i in range(gt_size):
        if ignored_gt[i] == -1:
            continue
        det_idx, valid, max_overlap, took_ignored = -1, _NO_DETECTION, 0.0, False
        for j in range(det_size):
            if ignored_det[j] == -1 or assigned[j] or below[j]:
                continue
            o = overlap[j, i]
            if not compute_fp and o > min_overlap and score[j] > valid:
                det_idx, valid = j, score[j]
            elif compute_fp and o > min_overlap and (o > max_overlap or took_ignored) \
                    and ignored_det[j] == 0:
                max_overlap, det_idx, valid, took_ignored = o, j, 1.0, False
            elif compute_fp and o > min_overlap and valid == _NO_DETECTION \
                    and ignored_det[j] == 1:
                det_idx, valid, took_ignored = j, 1.0, True
        if valid == _NO_DETECTION:
            continue
        assigned[det_idx] = True
        if ignored_gt[i] == 1 or ignored_det[det_idx] == 1:
            continue
        tp += 1
        found.append(score[det_idx])
    if compute_fp:
        fp = sum(1 for j in range(det_size)
                 if not (assigned[j] or ignored_det[j] != 0 or below[j]))
    return tp, fp, found


def kitti_r40(frames, min_overlap):
    """KITTI's AP_R40 (a fraction of 1) of one class at IoU ``min_overlap`` over
    ``frames``: a list of (overlap (D, G) IoU of the frame's detections with its boxes,
    ignored_gt (G,) 0 or 1, ignored_det (D,) 0 or 1, score (D,)), the boxes and
    detections of the class in their order. None without a counted box."""
    frames = [(np.asarray(o, np.float64).reshape(len(d), len(g)), list(map(int, g)),
               list(map(int, d)), [float(v) for v in s]) for o, g, d, s in frames]
    n_gt = sum(g.count(0) for _, g, _, _ in frames)
    if n_gt == 0:
        return None
    scores = []
    for o, g, d, s in frames:
        scores += _statistics(o, g, d, s, min_overlap, 0.0, False)[2]
    thresholds = get_thresholds(scores, n_gt)
    precision = np.zeros(N_SAMPLE_PTS)
    cache = {}
    for t, thresh in enumerate(thresholds):
        tp = fp = 0
        for k, (o, g, d, s) in enumerate(frames):
            kept = tuple(v >= thresh for v in s)  # the frame's result depends on these
            key = (k, kept)
            if key not in cache:
                cache[key] = _statistics(o, g, d, s, min_overlap, thresh, True)[:2]
            tp += cache[key][0]
            fp += cache[key][1]
        with np.errstate(invalid="ignore", divide="ignore"):
            precision[t] = np.float64(tp) / np.float64(tp + fp)
    for t in range(len(thresholds)):
        precision[t] = np.max(precision[t:])
    return float(np.sum(precision[1:]) / 40)


def class_frames(overlaps, det, gt, gt_ignore, det_ignore, label):
    """``kitti_r40``'s frames of one class from an evaluation's ``matching.Overlaps``
    (every same-frame, same-class pair), its ``Boxes`` and don't-care flags."""
    gt_rows = np.flatnonzero(gt.label == label)
    det_rows = np.flatnonzero(det.label == label)
    frames = np.union1d(gt.frame[gt_rows], det.frame[det_rows])
    iou = {}
    for d_, g_, v in zip(overlaps.det.tolist(), overlaps.gt.tolist(), overlaps.iou.tolist()):
        iou[(d_, g_)] = v
    out = []
    for f in frames:
        g = gt_rows[gt.frame[gt_rows] == f]
        d = det_rows[det.frame[det_rows] == f]
        o = np.array([[iou.get((a, b), 0.0) for b in g] for a in d]).reshape(len(d), len(g))
        out.append((o, gt_ignore[g].astype(int), det_ignore[d].astype(int), det.score[d]))
    return out


__all__ = ["class_frames", "get_thresholds", "kitti_r40"]
