"""Greedy matching: score order, one detection per ground-truth box, don't-care boxes on
either side, and frames and classes kept apart."""

import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.matching import FP, IGNORED, TP, greedy_match, match

CAR, PED = 11, 12


def car(x=0.0, y=0.0, yaw=0.0):
    return [x, y, 0.8, 4.0, 2.0, 1.5, yaw]


def test_detections_go_in_score_order_not_iou_order():
    # The better-placed detection scores lower and finds the box taken.
    iou = np.array([[0.6], [0.95]])
    status, gt, best, gt_det = greedy_match(iou, [0.9, 0.8], 0.5)
    assert status.tolist() == [TP, FP]
    assert gt.tolist() == [0, -1]
    assert best.tolist() == [0.6, 0.95]
    assert gt_det.tolist() == [0]


def test_a_detection_takes_the_free_box_it_overlaps_most():
    iou = np.array([[0.6, 0.8, 0.0],
                    [0.7, 0.9, 0.55],
                    [0.0, 0.0, 0.4]])
    status, gt, best, gt_det = greedy_match(iou, [0.5, 0.9, 0.7], 0.5)
    # Row 1 (0.9) takes box 1; row 2 (0.7) reaches nothing; row 0 (0.5) takes box 0.
    assert status.tolist() == [TP, TP, FP]
    assert gt.tolist() == [0, 1, -1]
    assert best.tolist() == [0.6, 0.9, 0.4]
    assert gt_det.tolist() == [0, 1, -1]


def test_threshold_is_inclusive_and_ties_keep_the_given_order():
    iou = np.array([[0.5], [0.5]])
    status, gt, _, _ = greedy_match(iou, [0.7, 0.7], 0.5)
    assert status.tolist() == [TP, FP] and gt.tolist() == [0, -1]
    status, _, _, _ = greedy_match(np.array([[0.4999999]]), [1.0], 0.5)
    assert status.tolist() == [FP]


def test_double_detection_is_a_false_positive():
    gt = Boxes(0, [car()], CAR, 1.0)
    det = Boxes(0, [car(0.1), car(0.0)], CAR, [0.9, 0.8])
    m = match(det, gt, 0.5, "bev")
    assert m.status.tolist() == [TP, FP]
    assert m.gt_det.tolist() == [0]
    assert (m.tp, m.fp, m.ignored, m.n_gt) == (1, 1, 0, 1)
    # The duplicate's IoU is reported against the box it lost: a perfect 1.
    assert m.iou[1] == pytest.approx(1.0)


def test_ignored_ground_truth_drops_one_detection_and_is_never_missed():
    gt = Boxes(0, [car(0), car(20)], CAR, 1.0)
    det = Boxes(0, [car(20.2), car(20.0), car(50)], CAR, [0.9, 0.8, 0.7])
    m = match(det, gt, 0.5, "3d", gt_ignore=[False, True])
    # First on the ignored box: dropped; the second on it: a duplicate, false.
    assert m.status.tolist() == [IGNORED, FP, FP]
    assert m.gt_index.tolist() == [1, -1, -1]
    assert m.n_gt == 1 and m.missed.tolist() == [True, False]
    assert m.gt_matched.tolist() == [False, True]


def test_counted_box_is_preferred_to_a_better_overlapping_ignored_one():
    iou = np.array([[0.55, 0.9]])
    status, gt, best, _ = greedy_match(iou, [1.0], 0.5, gt_ignore=[False, True])
    assert status.tolist() == [TP] and gt.tolist() == [0] and best.tolist() == [0.55]
    # Below the threshold for the counted box: the ignored one absorbs it.
    status, gt, _, _ = greedy_match(np.array([[0.45, 0.9]]), [1.0], 0.5,
                                    gt_ignore=[False, True])
    assert status.tolist() == [IGNORED] and gt.tolist() == [1]


def test_ignored_detections_count_only_when_they_find_a_counted_box():
    gt = Boxes(0, [car(0), car(30)], CAR, 1.0)
    det = Boxes(0, [car(0.5), car(60), car(30.1)], CAR, [0.9, 0.8, 0.3])
    m = match(det, gt, 0.5, "bev", gt_ignore=[False, True],
              det_ignore=[True, True, True])
    assert m.status.tolist() == [TP, IGNORED, IGNORED]
    assert m.gt_index.tolist() == [0, -1, 1]
    m = match(det, gt, 0.5, "bev", det_ignore=[False, True, False])
    assert m.status.tolist() == [TP, IGNORED, TP]


def test_classes_are_kept_apart():
    gt = Boxes(0, [car(0), car(10)], [CAR, PED], 1.0)
    det = Boxes(0, [car(0), car(10)], [PED, CAR], [0.9, 0.8])
    m = match(det, gt, 0.5)
    assert m.status.tolist() == [FP, FP]
    assert m.iou.tolist() == [0.0, 0.0]
    assert m.missed.tolist() == [True, True]


def test_frames_are_kept_apart():
    gt = Boxes([0, 1], [car(0), car(10)], CAR, 1.0)
    det = Boxes([1, 0, 1], [car(0), car(0), car(10)], CAR, [0.9, 0.8, 0.7])
    m = match(det, gt, 0.7)
    assert m.status.tolist() == [FP, TP, TP]
    assert m.gt_index.tolist() == [-1, 0, 1]
    assert m.gt_det.tolist() == [1, 2]


def test_shifted_box_has_the_iou_geometry_predicts():
    yaw = 0.7
    gt = Boxes(3, [car(5, 5, yaw)], CAR, 1.0)
    det = Boxes(3, [car(5 + math.cos(yaw), 5 + math.sin(yaw), yaw)], CAR, 0.6)
    for threshold, status in ((0.5, TP), (0.6, TP), (0.7, FP)):
        m = match(det, gt, threshold, "3d")
        assert m.status.tolist() == [status]
        assert m.iou[0] == pytest.approx(0.6, abs=1e-12)


def test_empty_sides_and_bad_input():
    gt = Boxes(0, [car()], CAR, 1.0)
    m = match(Boxes.empty(), gt)
    assert m.n_gt == 1 and m.missed.tolist() == [True]
    m = match(Boxes(0, [car()], CAR, 0.5), Boxes.empty())
    assert m.status.tolist() == [FP] and m.gt_index.tolist() == [-1]
    with pytest.raises(InputError, match="one flag per box"):
        match(Boxes.empty(), gt, gt_ignore=[True, False])
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        match(Boxes.empty(), gt, threshold=0)
    with pytest.raises(InputError, match="bev, 3d"):
        match(Boxes.empty(), gt, kind="image")


def naive_match(iou, score, threshold, gt_ignore, det_ignore):
    """The rules written out directly, one detection and one box at a time."""
    d, g = iou.shape
    status, gt_index, taken = [FP] * d, [-1] * d, {}
    for k in sorted(range(d), key=lambda k: -score[k]):  # sorted() is stable
        free = [j for j in range(g) if j not in taken and iou[k, j] >= threshold]
        counted = [j for j in free if not gt_ignore[j]]
        pick = counted or [j for j in free if gt_ignore[j]]
        if pick:
            j = max(pick, key=lambda j: (iou[k, j], -j))
            status[k] = TP if counted else IGNORED
            gt_index[k] = j
            taken[j] = k
        elif det_ignore[k]:
            status[k] = IGNORED
    return status, gt_index, [taken.get(j, -1) for j in range(g)]


def test_agrees_with_the_rules_written_out_on_random_tables():
    rng = np.random.default_rng(9)
    for _ in range(300):
        d, g = rng.integers(0, 9, 2)
        # Coarse values, so that IoUs and scores tie often.
        iou = rng.integers(0, 11, (d, g)) / 10 * (rng.random((d, g)) < 0.6)
        score = rng.integers(0, 5, d) / 4
        gt_ignore = rng.random(g) < 0.3
        det_ignore = rng.random(d) < 0.3
        status, gt_index, best, gt_det = greedy_match(iou, score, 0.5, gt_ignore,
                                                      det_ignore)
        want = naive_match(iou, score, 0.5, gt_ignore, det_ignore)
        assert (status.tolist(), gt_index.tolist(), gt_det.tolist()) == want
        matched = gt_index >= 0
        assert best[matched].tolist() == iou[matched, gt_index[matched]].tolist()
        assert best[~matched].tolist() == iou[~matched].max(axis=1, initial=0).tolist()
