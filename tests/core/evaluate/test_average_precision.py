"""Average precision: hand-worked curves for AP_R40 and VOC AP, and whole evaluations
whose answers the geometry fixes."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.average_precision import (
    UNDEFINED,
    ap_r40,
    ap_voc,
    evaluate,
    precision_recall,
)
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.matching import FP, IGNORED, TP

CAR, PED, CYC = 11, 12, 18


def test_hand_worked_curve_five_boxes():
    # Seven detections by falling score: TP FP TP TP FP FP TP, five boxes (one missed).
    #  k  TP  precision  recall
    #  1   1   1/1        0.2
    #  2   1   1/2        0.2
    #  3   2   2/3        0.4
    #  4   3   3/4        0.6
    #  5   3   3/5        0.6
    #  6   3   3/6        0.6
    #  7   4   4/7        0.8
    status = [TP, FP, TP, TP, FP, FP, TP]
    recall, precision, score = precision_recall(np.linspace(0.9, 0.3, 7), status, 5)
    np.testing.assert_allclose(recall, [0.2, 0.2, 0.4, 0.6, 0.6, 0.6, 0.8], rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(precision, [1, 1 / 2, 2 / 3, 3 / 4, 3 / 5, 3 / 6, 4 / 7],
                               rtol=0, atol=1e-15)
    # R40: best precision at recall >= r. r = 1/40..8/40 (<= 0.2): 1; 9/40..24/40
    # (<= 0.6): 3/4; 25/40..32/40 (<= 0.8): 4/7; 33/40..1: 0.
    # (8 * 1 + 16 * 3/4 + 8 * 4/7) / 40 = (20 + 32/7) / 40 = 43/70.
    assert ap_r40(recall, precision) == pytest.approx(43 / 70, abs=1e-9)
    # VOC: envelope 1, .75, .75, 4/7 on the recall steps 0-.2, .2-.4, .4-.6, .6-.8,
    # then 0 to recall 1: .2 * (1 + .75 + .75 + 4/7) = 43/70 as well (recall on the
    # 1/40 grid).
    assert ap_voc(recall, precision) == pytest.approx(43 / 70, abs=1e-9)


def test_hand_worked_curve_three_boxes_separates_r40_from_voc():
    # TP FP TP, three boxes: recall 1/3, 1/3, 2/3; precision 1, 1/2, 2/3.
    recall, precision, _ = precision_recall([0.9, 0.8, 0.7], [TP, FP, TP], 3)
    # R40: r <= 1/3 (k = 1..13): 1; r <= 2/3 (k = 14..26, 26/40 = .65): 2/3; k = 27..40:
    # 0.  (13 + 13 * 2/3) / 40 = 13/24.
    assert ap_r40(recall, precision) == pytest.approx(13 / 24, abs=1e-9)
    # VOC: 1/3 * 1 + 1/3 * 2/3 + 1/3 * 0 = 5/9.
    assert ap_voc(recall, precision) == pytest.approx(5 / 9, abs=1e-9)


def test_curve_drops_ignored_sorts_stably_and_edges():
    recall, precision, score = precision_recall(
        [0.2, 0.9, 0.5, 0.5, 0.7], [TP, IGNORED, FP, TP, TP], 4)
    assert score.tolist() == [0.7, 0.5, 0.5, 0.2]
    assert recall.tolist() == [0.25, 0.25, 0.5, 0.75]
    assert precision.tolist() == [1.0, 0.5, 2 / 3, 0.75]
    # No detections: AP 0 where there is ground truth.
    recall, precision, _ = precision_recall([], [], 3)
    assert ap_r40(recall, precision) == 0.0 and ap_voc(recall, precision) == 0.0
    # Every box found, nothing false: 1.
    recall, precision, _ = precision_recall([1, 1, 1], [TP, TP, TP], 3)
    assert ap_r40(recall, precision) == 1.0 and ap_voc(recall, precision) == 1.0


def test_r40_against_its_definition_on_random_curves():
    rng = np.random.default_rng(4)
    for _ in range(50):
        n_gt = int(rng.integers(1, 70))
        hits = rng.random(int(rng.integers(1, 90))) < 0.6
        hits[np.cumsum(hits) > n_gt] = False
        recall, precision, _ = precision_recall(-np.arange(len(hits)),
                                                np.where(hits, TP, FP), n_gt)
        tp = np.cumsum(hits)
        expected = 0.0
        for k in range(1, 41):
            reach = [precision[i] for i in range(len(tp)) if tp[i] * 40 >= k * n_gt]
            expected += max(reach, default=0.0) / 40
        assert ap_r40(recall, precision) == pytest.approx(expected, abs=1e-12)


def box(x, y=0.0, length=4.0, width=2.0, yaw=0.0, z=0.8, height=1.5):
    return [x, y, z, length, width, height, yaw]


def scene():
    """Three frames of cars, pedestrians and a cyclist."""
    frames = [0, 0, 0, 1, 1, 2, 2]
    boxes = [box(10, 2), box(25, -3, yaw=1.2), box(8, 6, 0.8, 0.7, 0.3),
             box(40, 1), box(5, -5, 1.8, 0.6, 2.0), box(60, 10, yaw=-0.4),
             box(12, 12, 0.7, 0.7)]
    labels = [CAR, CAR, PED, CAR, CYC, CAR, PED]
    return Boxes(frames, boxes, labels, 1.0, points=[50, 40, 30, 20, 10, 5, 2])


def test_ground_truth_as_detections_scores_one():
    gt = scene()
    result = evaluate(gt, gt)
    assert json.loads(json.dumps(result, allow_nan=False)) == result
    assert result["iou_thresholds"] == [0.3, 0.5, 0.7]
    for name in ("vehicle", "pedestrian", "cyclist"):
        for kind in ("bev", "3d"):
            for threshold in ("0.3", "0.5", "0.7"):
                record = result["classes"][name]["all"][kind][threshold]
                assert record["ap_r40"] == 1.0 and record["ap_voc"] == 1.0
                assert record["fp"] == 0 and record["missed"] == 0
    assert result["classes"]["vehicle"]["all"]["3d"]["0.7"]["tp"] == 4


def test_a_box_moved_along_its_length_scores_by_its_iou():
    # 4 x 2 box moved 1 m along its heading: IoU 3/5, a hit at 0.3 and 0.5, not at 0.7.
    yaw = 2.5
    gt = Boxes(0, [box(20, 20, yaw=yaw)], CAR, 1.0)
    det = Boxes(0, [box(20 + math.cos(yaw), 20 + math.sin(yaw), yaw=yaw)], CAR, 0.8)
    result = evaluate(gt, det, classes=["car"])
    assert list(result["classes"]) == ["vehicle"]
    for kind in ("bev", "3d"):
        runs = result["classes"]["vehicle"]["all"][kind]
        for threshold in ("0.3", "0.5"):
            assert runs[threshold]["ap_r40"] == 1.0 and runs[threshold]["tp"] == 1
        assert runs["0.7"]["ap_r40"] == 0.0 and runs["0.7"]["ap_voc"] == 0.0
        assert (runs["0.7"]["tp"], runs["0.7"]["fp"], runs["0.7"]["missed"]) == (0, 1, 1)


def test_no_ground_truth_is_undefined_and_no_detections_is_zero():
    gt = Boxes(0, [box(10)], CAR, 1.0)
    det = Boxes(0, [box(30, 5, 0.7, 0.7)], PED, 0.9)
    result = evaluate(gt, det, iou_thresholds=[0.5], kinds="bev")
    ped = result["classes"]["pedestrian"]["all"]["bev"]["0.5"]
    assert ped["ap_r40"] is None and ped["ap_voc"] is None and ped["note"] == UNDEFINED
    assert (ped["gt"], ped["fp"], ped["recall"]) == (0, 1, [])
    vehicle = result["classes"]["vehicle"]["all"]["bev"]["0.5"]
    assert vehicle["ap_r40"] == 0.0 and vehicle["ap_voc"] == 0.0
    assert (vehicle["gt"], vehicle["missed"], vehicle["precision"]) == (1, 1, [])


def test_pooled_frames_and_ignored_boxes():
    # Frame 0: a found car (0.9), a duplicate (0.6); frame 1: a found car (0.8), a
    # detection of an ignored car (0.95, dropped); frame 2: a missed car, a false
    # alarm (0.7). Counted cars 3; pooled TP FP TP FP by score 0.9 0.8 0.7 0.6.
    gt = Boxes([0, 1, 1, 2], [box(10), box(20), box(40), box(15)], CAR, 1.0)
    det = Boxes([0, 0, 1, 1, 2], [box(10), box(10.3), box(20), box(40), box(-30)],
                CAR, [0.9, 0.6, 0.8, 0.95, 0.7])
    result = evaluate(gt, det, gt_ignore=[False, False, True, False],
                      iou_thresholds=[0.5], kinds=["3d"], classes=["vehicle"])
    record = result["classes"]["vehicle"]["all"]["3d"]["0.5"]
    assert (record["tp"], record["fp"], record["gt"], record["missed"]) == (2, 2, 3, 1)
    assert (record["ignored"], record["gt_ignored"]) == (1, 1)
    assert record["score"] == [0.9, 0.8, 0.7, 0.6]
    assert record["recall"] == [1 / 3, 2 / 3, 2 / 3, 2 / 3]
    assert record["precision"] == [1.0, 1.0, 2 / 3, 0.5]
    # R40: r <= 2/3 (k = 1..26): 1, the rest 0 -> 26/40; VOC: 2/3.
    assert record["ap_r40"] == pytest.approx(26 / 40, abs=1e-12)
    assert record["ap_voc"] == pytest.approx(2 / 3, abs=1e-12)


def test_distance_bins():
    sensor = (100.0, 50.0)
    # Cars at 10, 30.5 and 60 m from the sensor along +X.
    gt = Boxes(0, [box(110, 50), box(130.5, 50), box(160, 50)], CAR, 1.0)
    # Found: the 10 m car, and the 30.5 m one by a box centred at 29.5 m (in the bin
    # below; IoU 3/5); a false alarm at 46 m; the 60 m car missed.
    det = Boxes(0, [box(110, 50), box(129.5, 50), box(145, 60)], CAR, [0.9, 0.8, 0.7])
    result = evaluate(gt, det, iou_thresholds=[0.5], kinds=["bev"], classes=[CAR],
                      distance_bins=[0, 30, 50, math.inf], sensor_xy=sensor)
    assert result["distance_bins"] == [[0.0, 30.0], [30.0, 50.0], [50.0, None]]
    everything = result["classes"]["vehicle"]["all"]["bev"]["0.5"]
    assert (everything["tp"], everything["fp"], everything["missed"]) == (2, 1, 1)
    near, middle, far = (b["bev"]["0.5"] for b in result["classes"]["vehicle"]["bins"])
    # 0-30 m: its car found; the 29.5 m detection took a box of another range (dropped,
    # counted as dropped here where it lies); the 46 m false alarm lies outside
    # (dropped, counted nowhere in this range).
    assert (near["tp"], near["fp"], near["gt"], near["ignored"]) == (1, 0, 1, 1)
    assert near["ap_r40"] == 1.0
    # 30-50 m: its car found by the detection centred just outside; the false alarm;
    # the 10 m detection took a box outside the range and lies outside: not counted.
    assert (middle["tp"], middle["fp"], middle["gt"], middle["ignored"]) == (1, 1, 1, 0)
    assert middle["precision"] == [1.0, 0.5] and middle["ap_voc"] == 1.0
    # 50 m and beyond: its car missed, nothing detected there.
    assert (far["tp"], far["fp"], far["gt"], far["ap_r40"]) == (0, 0, 1, 0.0)


def test_bad_requests_say_what_to_do():
    gt = scene()
    with pytest.raises(InputError, match="sensor"):
        evaluate(gt, gt, distance_bins=[0, 30])
    with pytest.raises(InputError, match="increasing"):
        evaluate(gt, gt, distance_bins=[30, 0], sensor_xy=(0, 0))
    with pytest.raises(InputError, match="unknown class"):
        evaluate(gt, gt, classes=["tram"])
    with pytest.raises(InputError, match="RLS evaluates"):
        evaluate(gt, gt, classes=[13])
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        evaluate(gt, gt, iou_thresholds=[1.5])
    with pytest.raises(InputError, match="bev, 3d"):
        evaluate(gt, gt, kinds=["2d"])
    bad = scene()
    bad.score[0] = 1.5
    with pytest.raises(InputError, match="detections"):
        evaluate(gt, bad)
