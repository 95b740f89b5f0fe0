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
the detection that took it (-1 for none). Indices are rows of the ``Boxes`` given.

``pair_overlaps`` works out the IoU of every same-frame, same-class pair once (one
vectorised call); ``match`` then runs over all groups in one pass, so several thresholds
and ignore masks share the geometry."""

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


def _greedy(n_det, n_gt, pair_det, pair_gt, pair_iou, score, threshold, gt_ignore,
            det_ignore):
    """The matching itself, on the candidate pairs (detection, ground truth, IoU) of any
    number of independent groups (a group's detections keep their relative order in the
    one score order, so matching all groups in one pass is matching each in turn).
    Returns (status, gt_index, best, gt_det) as ``greedy_match``."""
    best = np.zeros(n_det)
    np.maximum.at(best, pair_det, pair_iou)
    status = np.where(det_ignore, IGNORED, FP).astype(np.int8)
    gt_index = np.full(n_det, -1, np.int64)
    gt_det = np.full(n_gt, -1, np.int64)
    keep = pair_iou >= threshold
    pair_det, pair_gt, pair_iou = pair_det[keep], pair_gt[keep], pair_iou[keep]
    # Each detection's candidates by falling IoU (ties: lower GT row first).
    order = np.lexsort((pair_gt, -pair_iou, pair_det))
    cand = pair_gt[order].tolist()
    cand_iou = pair_iou[order].tolist()
    start = np.searchsorted(pair_det[order], np.arange(n_det + 1)).tolist()
    ignore = gt_ignore.tolist()
    taken = [-1] * n_gt
    for k in np.argsort(-score, kind="stable").tolist():
        counted = dropped = -1
        for c in range(start[k], start[k + 1]):
            j = cand[c]
            if taken[j] >= 0:
                continue
            if not ignore[j]:
                counted = c
                break
            if dropped < 0:
                dropped = c
        c = counted if counted >= 0 else dropped
        if c < 0:
            continue
        status[k] = TP if counted >= 0 else IGNORED
        gt_index[k] = j = cand[c]
        best[k] = cand_iou[c]
        taken[j] = k
    gt_det[:] = taken
    return status, gt_index, best, gt_det


def greedy_match(iou, score, threshold, gt_ignore=None, det_ignore=None):
    """Match one frame and class: ``iou`` (D, G) of detections with ground truth,
    ``score`` (D,). Returns (status (D,) int8, gt_index (D,) int64, best (D,) float64,
    gt_det (G,) int64) as described in the module docstring; indices are local."""
    threshold = check_threshold(threshold)
    iou = np.asarray(iou, np.float64)
    d, g = iou.shape
    score = np.asarray(score, np.float64).reshape(d)
    pair_det, pair_gt = (x.reshape(-1) for x in np.indices((d, g)))
    return _greedy(d, g, pair_det, pair_gt, iou.reshape(-1), score, threshold,
                   as_flags(gt_ignore, g, "gt_ignore"),
                   as_flags(det_ignore, d, "det_ignore"))


@dataclass
class Overlaps:
    """The IoU of every same-frame, same-class (detection, ground truth) pair, worked out
    once for any number of matchings (thresholds, ignore masks)."""
    det: np.ndarray   # (P,) int64 detection rows
    gt: np.ndarray    # (P,) int64 ground-truth rows
    iou: np.ndarray   # (P,) float64
    kind: str
    n_det: int
    n_gt: int


def _groups(detections, ground_truth):
    """[(detection rows, ground-truth rows)] of each (frame, label) either set holds."""
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
    """``Overlaps`` of ``detections`` and ``ground_truth`` (both ``Boxes``): every pair
    of the same frame and class, by ``kind`` 'bev' or '3d' IoU."""
    if kind not in IOU_KINDS:
        raise InputError(f"unknown overlap kind '{kind}': choose one of "
                         + ", ".join(IOU_KINDS))
    none = np.zeros(0, np.int64)
    groups = [(d, g) for d, g in _groups(detections, ground_truth) if len(d) and len(g)]
    pair_det = np.concatenate([np.repeat(d, len(g)) for d, g in groups] + [none])
    pair_gt = np.concatenate([np.tile(g, len(d)) for d, g in groups] + [none])
    values = iou_at(detections.box, ground_truth.box, pair_det, pair_gt, kind)
    return Overlaps(pair_det, pair_gt, values, kind, len(detections), len(ground_truth))


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
    elif (overlaps.kind, overlaps.n_det, overlaps.n_gt) != (kind, d_count, g_count):
        raise InputError(f"the overlaps given are {overlaps.kind} IoU of "
                         f"{overlaps.n_det} detections and {overlaps.n_gt} boxes, not "
                         f"{kind} of {d_count} and {g_count}: work them out again with "
                         "pair_overlaps")
    status, gt_index, best, gt_det = _greedy(
        d_count, g_count, overlaps.det, overlaps.gt, overlaps.iou, detections.score,
        threshold, gt_ignore, det_ignore)
    return Matches(status, gt_index, best, gt_det, gt_ignore, threshold, kind)
