"""Detections matched to ground truth, one frame and one class at a time, greedily.

Within each (frame, class) group the detections are taken in descending score (ties in
their given order: a stable sort) and each takes, of the ground-truth boxes not yet
taken, the one it overlaps most, if that IoU is at least the threshold (``>=``, as
OpenCOOD's ``caluclate_tp_fp``; KITTI's evaluation asks for ``>``). A ground-truth box is
taken at most once, so a second detection of the same object is a false positive.
Overlap is BEV or 3D IoU (``overlap.py``); ties in IoU go to the lower GT index.

Don't-care (KITTI's ignored boxes). Ground truth may be flagged ``gt_ignore`` (too few
points, centre outside the region of interest): such boxes are never misses, and a
detection that reaches no counted box but overlaps an ignored one at the threshold is
matched to it and dropped, neither a true nor a false positive. An ignored box, like a
counted one, takes one detection: a second detection on it is a false positive (KITTI's
``compute_statistics_jit`` does the same). A detection prefers a counted box to an
ignored one whatever their IoUs.

Detections may be flagged ``det_ignore`` (say, centred outside the region): such a
detection that matches a counted ground-truth box is a true positive as any other (the
object was found; only false alarms outside the region are forgiven), and otherwise it
is dropped. KITTI differs here: its ignored detections never count, and a counted box
they match leaves both the true positives and the misses.

Results are ``Matches``: per detection its status (``TP`` 1, ``FP`` 0, ``IGNORED`` -1),
the GT index it took (-1 for none) and an IoU (with the box it took; for the others the
best IoU with any ground truth of its frame and class, 0 if none); per ground-truth box
the detection that took it (-1 for none). Indices are rows of the ``Boxes`` given."""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .overlap import IOU_KINDS, iou_at

TP, FP, IGNORED = 1, 0, -1


@dataclass
class Matches:
    status: np.ndarray     # (D,) int8: TP, FP or IGNORED
    gt_index: np.ndarray   # (D,) int64: the ground-truth row taken, -1 for none
    iou: np.ndarray        # (D,) float64: see the module docstring
    gt_det: np.ndarray     # (G,) int64: the detection row that took each GT, -1 for none
    gt_ignore: np.ndarray  # (G,) bool: ground truth that does not count
    threshold: float = 0.5
    kind: str = "3d"

    @property
    def tp(self):
        return int((self.status == TP).sum())

    @property
    def fp(self):
        return int((self.status == FP).sum())

    @property
    def ignored(self):
        """Detections dropped (neither true nor false positives)."""
        return int((self.status == IGNORED).sum())

    @property
    def n_gt(self):
        """Counted ground truth: the recall's denominator."""
        return int((~self.gt_ignore).sum())

    @property
    def gt_matched(self):
        """(G,) bool: ground truth taken by a detection."""
        return self.gt_det >= 0

    @property
    def missed(self):
        """(G,) bool: counted ground truth no detection took (false negatives)."""
        return ~self.gt_ignore & (self.gt_det < 0)


def check_threshold(threshold):
    """An IoU threshold as a float in (0, 1]; ``InputError`` otherwise."""
    try:
        value = float(threshold)
    except (TypeError, ValueError):
        raise InputError(f"IoU threshold {threshold!r} is not a number") from None
    if not 0.0 < value <= 1.0:
        raise InputError(f"IoU threshold {threshold!r} must lie in (0, 1]: at 0 every "
                         "detection would match")
    return value


def as_flags(mask, n, name):
    """(n,) bool from a mask of one flag per box (None: all False); ``InputError`` if
    its length is not n."""
    if mask is None:
        return np.zeros(n, bool)
    mask = np.asarray(mask)
    if mask.shape != (n,):
        raise InputError(f"{name} must hold one flag per box ({n}), got shape "
                         f"{mask.shape}")
    return mask.astype(bool)


def greedy_match(iou, score, threshold, gt_ignore=None, det_ignore=None):
    """Match one frame and class: ``iou`` (D, G) of detections with ground truth,
    ``score`` (D,). Returns (status (D,) int8, gt_index (D,) int64, best (D,) float64,
    gt_det (G,) int64) as described in the module docstring; indices are local."""
    threshold = check_threshold(threshold)
    iou = np.asarray(iou, np.float64)
    d, g = iou.shape
    score = np.asarray(score, np.float64).reshape(d)
    gt_ignore = as_flags(gt_ignore, g, "gt_ignore")
    det_ignore = as_flags(det_ignore, d, "det_ignore")
    status = np.full(d, FP, np.int8)
    gt_index = np.full(d, -1, np.int64)
    best = iou.max(axis=1, initial=0.0) if g else np.zeros(d)
    gt_det = np.full(g, -1, np.int64)
    reach = iou >= threshold
    for k in np.argsort(-score, kind="stable"):
        row = np.where(reach[k] & (gt_det < 0), iou[k], -1.0)
        counted = np.where(gt_ignore, -1.0, row)
        j = int(np.argmax(counted)) if g else 0
        if g and counted[j] >= 0:
            status[k] = TP
        else:
            dropped = np.where(gt_ignore, row, -1.0)
            j = int(np.argmax(dropped)) if g else 0
            if g and dropped[j] >= 0:
                status[k] = IGNORED
            else:
                if det_ignore[k]:
                    status[k] = IGNORED
                continue
        gt_index[k] = j
        gt_det[j] = k
        best[k] = iou[k, j]
    return status, gt_index, best, gt_det


def _groups(detections, ground_truth):
    """{(frame, label): (detection rows, ground-truth rows)} over both sets."""
    keys_d = np.stack([detections.frame, detections.label], axis=1)
    keys_g = np.stack([ground_truth.frame, ground_truth.label], axis=1)
    keys, inverse = np.unique(np.concatenate([keys_d, keys_g]), axis=0,
                              return_inverse=True)
    inverse = inverse.reshape(-1)
    gd, gg = inverse[:len(keys_d)], inverse[len(keys_d):]
    order_d = np.argsort(gd, kind="stable")
    order_g = np.argsort(gg, kind="stable")
    cut_d = np.searchsorted(gd[order_d], np.arange(len(keys) + 1))
    cut_g = np.searchsorted(gg[order_g], np.arange(len(keys) + 1))
    return [(order_d[cut_d[k]:cut_d[k + 1]], order_g[cut_g[k]:cut_g[k + 1]])
            for k in range(len(keys))]


def pair_overlaps(detections, ground_truth, kind="3d"):
    """The IoU table of every (frame, class) group, worked out once for any number of
    matchings (thresholds, ignore masks): a list of (detection rows, ground-truth rows,
    IoU (D, G)). ``kind`` is 'bev' or '3d'."""
    if kind not in IOU_KINDS:
        raise InputError(f"unknown overlap kind '{kind}': choose one of "
                         + ", ".join(IOU_KINDS))
    groups = _groups(detections, ground_truth)
    pairs_d = [np.repeat(d, len(g)) for d, g in groups]
    pairs_g = [np.tile(g, len(d)) for d, g in groups]
    values = iou_at(detections.box, ground_truth.box,
                    np.concatenate(pairs_d + [np.zeros(0, np.int64)]),
                    np.concatenate(pairs_g + [np.zeros(0, np.int64)]), kind)
    cuts = np.cumsum([0] + [len(d) * len(g) for d, g in groups])
    return [(d, g, values[cuts[k]:cuts[k + 1]].reshape(len(d), len(g)))
            for k, (d, g) in enumerate(groups)]


def match(detections, ground_truth, threshold=0.5, kind="3d", gt_ignore=None,
          det_ignore=None, overlaps=None):
    """Match ``detections`` to ``ground_truth`` (both ``Boxes``) frame by frame and class
    by class at an IoU ``threshold`` of ``kind`` 'bev' or '3d'. ``gt_ignore`` and
    ``det_ignore`` are (G,) and (D,) bool masks (don't-care, see the module docstring).
    ``overlaps`` is ``pair_overlaps(detections, ground_truth, kind)`` when several
    matchings share it. Returns ``Matches``."""
    threshold = check_threshold(threshold)
    d_count, g_count = len(detections), len(ground_truth)
    gt_ignore = as_flags(gt_ignore, g_count, "gt_ignore")
    det_ignore = as_flags(det_ignore, d_count, "det_ignore")
    if overlaps is None:
        overlaps = pair_overlaps(detections, ground_truth, kind)
    status = np.full(d_count, FP, np.int8)
    gt_index = np.full(d_count, -1, np.int64)
    best = np.zeros(d_count)
    gt_det = np.full(g_count, -1, np.int64)
    for d, g, table in overlaps:
        if not len(d):
            continue
        s, j, b, taken = greedy_match(table, detections.score[d], threshold,
                                      gt_ignore[g], det_ignore[d])
        status[d] = s
        gt_index[d] = np.where(j >= 0, g[np.maximum(j, 0)] if len(g) else -1, -1)
        best[d] = b
        if len(g):
            gt_det[g] = np.where(taken >= 0, d[np.maximum(taken, 0)], -1)
    return Matches(status, gt_index, best, gt_det, gt_ignore, threshold, kind)
