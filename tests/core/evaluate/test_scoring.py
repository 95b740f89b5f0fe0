"""score: what counts as ground truth (region, min points, don't-care), several sensors
merged into one, counts per frame and distance, and each bad input one InputError."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.ground_truth_files import GroundTruth, read_ground_truth
from rls_addon.core.evaluate.kitti_labels import write_detections
from rls_addon.core.evaluate.readers import DetectionFiles, read_detection_files
from rls_addon.core.evaluate.scoring import frames_text, merge_ground_truth, score

from .builders import kitti_dataset, pose

CAR, PED = 11, 12
REGION = [(-10, -10), (10, -10), (10, 10), (-10, 10)]
SIZE = (4.0, 2.0, 1.5)


def car(x, y, yaw=0.0, size=SIZE):
    return [x, y, size[2] / 2, *size, yaw]


def truth(rows, frames=(1,), sensor="pole", at=(0.0, 0.0, 6.0), speed=None):
    """GroundTruth of rows (frame, instance, label, box, points) seen by a sensor at
    ``at`` in every frame (``speed``: each box's, m/s)."""
    rows = list(rows)
    boxes = Boxes([r[0] for r in rows], [r[3] for r in rows], [r[2] for r in rows], 1.0,
                  [r[4] for r in rows]) if rows else Boxes.empty()
    poses = {f: pose(*at) for f in frames}
    return GroundTruth(boxes, list(frames), poses, np.full(len(rows), np.nan),
                       np.array([r[1] for r in rows], np.int64), sensor,
                       None if speed is None else np.asarray(speed, np.float64))


def dets(rows):
    """Boxes of rows (frame, label, box, score)."""
    return Boxes([r[0] for r in rows], [r[2] for r in rows], [r[1] for r in rows],
                 [r[3] for r in rows])


def record(result, kind="bev", threshold="0.5", cls="vehicle"):
    return result["classes"][cls]["all"][kind][threshold]


def test_region_counts_centres_inside_and_forgives_what_lies_outside():
    gt = truth([
        (1, 1, CAR, car(0, 0), 100),      # A: inside
        (1, 2, CAR, car(30, 0), 100),     # B: outside
        (1, 3, CAR, car(11, -5), 100),    # C: centred outside, reaching in
        (1, 4, CAR, car(9.5, 5), 100),    # D: centred inside, reaching out
    ])
    det = dets([
        (1, CAR, car(0, 0), 0.9),         # A found: TP
        (1, CAR, car(30, 0), 0.85),       # B found: outside, dropped
        (1, CAR, car(9.8, -5), 0.8),      # C found, centred inside: C is don't-care
        (1, CAR, car(0, 6), 0.7),         # false alarm inside: FP
        (1, CAR, car(40, 6), 0.6),        # false alarm outside: dropped
        (1, CAR, car(10.3, 5), 0.5),      # D found, centred outside: TP all the same
    ])
    r = score(gt, det, region=REGION, iou_thresholds=(0.5,))
    rec = record(r)
    assert (rec["tp"], rec["fp"], rec["gt"], rec["missed"], rec["ignored"]) == (2, 1, 2, 0, 3)
    assert rec["gt_ignored"] == 2
    # the curve: TP (0.9), FP (0.7), TP (0.5): precision 1, 1/2, 2/3 at recall 1/2, 1/2, 1
    assert rec["precision"] == [1.0, 0.5, pytest.approx(2 / 3)]
    assert rec["recall"] == [0.5, 0.5, 1.0]
    # R40: 1 up to recall 1/2 (20 points), then 2/3 (20 points)
    assert rec["ap_r40"] == pytest.approx((20 + 20 * 2 / 3) / 40)
    assert rec["ap_voc"] == pytest.approx(0.5 * 1 + 0.5 * 2 / 3)
    assert [m["status"]["bev"]["0.5"] for m in r["matches"]] == \
        ["tp", "ignored", "ignored", "fp", "ignored", "tp"]
    assert [m["in_region"] for m in r["matches"]] == [True, False, True, True, False, False]
    # D's detection is shifted 0.8 m along its length: BEV IoU (4 - 0.8) / (4 + 0.8)
    assert r["matches"][5]["best"]["bev"] == {"iou": pytest.approx(3.2 / 4.8, abs=1e-12),
                                             "instance": 4}
    assert r["ground_truth"]["counted"] == 2 and r["ground_truth"]["ignored_outside_region"] == 2
    assert r["detections"] == {"boxes": 6, "outside_region": 3, "not_scored_classes": 0}
    assert r["region"]["area_m2"] == 400.0
    json.dumps(r, allow_nan=False)  # strict JSON throughout
    # without a region every box counts and the far false alarm is false
    everywhere = record(score(gt, det, iou_thresholds=(0.5,)))
    assert (everywhere["tp"], everywhere["fp"], everywhere["gt"]) == (4, 2, 4)


def test_boxes_with_too_few_points_are_dont_care():
    gt = truth([(1, 1, CAR, car(0, 0), 4), (1, 2, CAR, car(0, 5), 5)])
    det = dets([(1, CAR, car(0, 0), 0.9)])
    rec = record(score(gt, det))            # default min_points 5
    assert (rec["tp"], rec["fp"], rec["ignored"], rec["gt"], rec["missed"],
            rec["gt_ignored"]) == (0, 0, 1, 1, 1, 1)
    assert rec["ap_r40"] == 0.0
    rec = record(score(gt, det, min_points=4))
    assert (rec["tp"], rec["fp"], rec["gt"], rec["missed"]) == (1, 0, 2, 1)
    assert rec["ap_r40"] == pytest.approx(0.5)  # recall 1/2 at precision 1: 20 of 40
    r = score(gt, det, min_points=4)
    assert r["ground_truth"]["ignored_few_points"] == 0 and r["min_points"] == 4


def test_several_sensors_are_scored_as_one():
    # object 7: 3 + 3 points (counted only together); object 8: 9 points from b alone.
    # b's box of object 7 (more points) is 0.1 m off a's.
    a = truth([(1, 7, CAR, car(0, 0), 3), (1, 8, CAR, car(20, 0), 0)], sensor="a",
              at=(-30.0, 0.0, 6.0))
    b = truth([(1, 7, CAR, car(0.1, 0), 4), (1, 8, CAR, car(20, 0), 9)], sensor="b",
              at=(25.0, 0.0, 6.0))
    merged = merge_ground_truth([a, b])
    assert merged.sensors == ["a", "b"]
    np.testing.assert_array_equal(merged.instance, [7, 8])
    np.testing.assert_array_equal(merged.boxes.points, [7, 9])
    np.testing.assert_array_equal(merged.points_by_sensor, [[3, 4], [0, 9]])
    assert merged.boxes.box[0, 0] == 0.1
    # distance from the nearest sensor: object 7 (b's box) is 24.9 m from b, 30.1 from a
    np.testing.assert_allclose(merged.distance(merged.boxes), [24.9, 5.0], rtol=0,
                               atol=1e-12)
    det = dets([(1, CAR, car(0.1, 0), 0.9), (1, CAR, car(20, 0), 0.8)])
    r = score([a, b], det)
    rec = record(r)
    assert (rec["tp"], rec["fp"], rec["gt"]) == (2, 0, 2)
    assert r["frames"][0]["sensors"] == {
        "a": {"position": [-30.0, 0.0, 6.0], "counted_alone": 0},
        "b": {"position": [25.0, 0.0, 6.0], "counted_alone": 1}}
    assert r["ground_truth"]["sensors"] == ["a", "b"]
    # either sensor alone: a counts nothing, b one box (object 8)
    with pytest.raises(InputError, match="no ground-truth box of vehicle, pedestrian, "
                                         "cyclist has >= 5 points"):
        score(a, det)
    assert record(score(b, det))["gt"] == 1


def test_sensors_must_cover_the_same_frames_once_each_with_instances():
    a = truth([(1, 7, CAR, car(0, 0), 9)], frames=(1, 2), sensor="a")
    b = truth([(1, 7, CAR, car(0, 0), 9)], frames=(1,), sensor="b")
    with pytest.raises(InputError, match=r"different frames: a has 1-2, b has 1; .*same "
                                         "frames with every sensor"):
        merge_ground_truth([a, b])
    with pytest.raises(InputError, match="sensor 'a' is given twice"):
        merge_ground_truth([a, a])
    c = truth([(1, 0, CAR, car(0, 0), 9)], frames=(1, 2), sensor="c")
    with pytest.raises(InputError, match="c has boxes without an instance id"):
        merge_ground_truth([a, c])


def test_counts_per_frame_add_up_to_the_totals():
    gt = truth([(1, 1, CAR, car(0, 0), 50), (1, 2, PED, [3, 3, 0.9, 0.6, 0.6, 1.8, 0], 20),
                (2, 1, CAR, car(1, 0), 50), (2, 3, CAR, car(-5, -5), 2),
                (3, 1, CAR, car(2, 0), 50)], frames=(1, 2, 3))
    det = dets([(1, CAR, car(0, 0), 0.9), (1, CAR, car(0, 7), 0.4),
                (2, CAR, car(1, 0), 0.8), (2, CAR, car(-5, -5), 0.7)])
    r = score(gt, det, classes=["Car", "pedestrian"], iou_thresholds=0.7, kinds="3d")
    assert list(r["classes"]) == ["vehicle", "pedestrian"]
    frames = {f["frame"]: f for f in r["frames"]}
    assert sorted(frames) == [1, 2, 3]
    got = {f: (e["all"]["gt"], e["all"]["gt_ignored"], e["all"]["detections"],
               e["all"]["3d"]["0.7"]) for f, e in frames.items()}
    assert got == {1: (2, 0, 2, {"tp": 1, "fp": 1, "ignored": 0, "missed": 1}),
                   2: (1, 1, 2, {"tp": 1, "fp": 0, "ignored": 1, "missed": 0}),
                   3: (1, 0, 0, {"tp": 0, "fp": 0, "ignored": 0, "missed": 1})}
    assert frames[1]["classes"]["pedestrian"]["3d"]["0.7"]["missed"] == 1
    assert frames[1]["sensors"]["pole"]["counted_alone"] == 2
    car_rec = record(r, "3d", "0.7")
    assert (car_rec["tp"], car_rec["fp"], car_rec["gt"], car_rec["missed"]) == (2, 1, 3, 1)
    assert record(r, "3d", "0.7", "pedestrian")["ap_r40"] == 0.0
    # detections that cover frames 1-2 only: frame 3's car is not a miss
    files = DetectionFiles(det, [1, 2], "kitti")
    r2 = score(gt, files, kinds="3d", iou_thresholds=0.7)
    assert [f["frame"] for f in r2["frames"]] == [1, 2]
    assert record(r2, "3d", "0.7")["gt"] == 2
    assert r2["notices"] == ["scored 2 of the ground truth's 3 frames: those the "
                             "detections cover (1-2)"]


def test_distance_bins_from_the_frames_sensor():
    # the sensor moves: at x = 0 in frame 1, x = 100 in frame 2; boxes 10 m and 40 m off
    gt = truth([(1, 1, CAR, car(10, 0), 50), (1, 2, CAR, car(40, 0), 50),
                (2, 1, CAR, car(110, 0), 50), (2, 2, CAR, car(60, 0), 50)], frames=(1, 2))
    gt.sensor_pose[2] = pose(100.0, 0.0, 6.0)
    det = dets([(1, CAR, car(10, 0), 0.9), (2, CAR, car(110, 0), 0.8),
                (2, CAR, car(60, 0), 0.7), (1, CAR, car(10, 25), 0.6)])
    r = score(gt, det, distance_bins=(0, 30, math.inf), iou_thresholds=(0.5,), kinds="bev")
    near, far = r["classes"]["vehicle"]["bins"]
    assert near["range_m"] == [0.0, 30.0] and far["range_m"] == [30.0, None]
    assert (near["bev"]["0.5"]["tp"], near["bev"]["0.5"]["fp"], near["bev"]["0.5"]["gt"]) \
        == (2, 1, 2)
    assert (far["bev"]["0.5"]["tp"], far["bev"]["0.5"]["gt"], far["bev"]["0.5"]["missed"]) \
        == (1, 2, 1)
    assert far["bev"]["0.5"]["ap_r40"] == 0.5
    assert [m["distance_m"] for m in r["matches"]] == [10.0, 10.0, 40.0,
                                                       pytest.approx(math.hypot(10, 25))]


def test_standing_and_moving_boxes_are_counted_apart():
    """Recall of the counted boxes that stand (under SUMO's halting speed, 0.1 m/s) and of
    those that move, per class, kind and threshold; a box of unknown speed is neither."""
    gt = truth([(1, 1, CAR, car(0, 0), 50), (1, 2, CAR, car(0, 5), 50),
                (1, 3, CAR, car(5, -5), 50), (1, 4, CAR, car(-5, -5), 50),
                (1, 5, CAR, car(30, 0), 50)],  # outside the region: not counted
               speed=[0.0, 0.09, 8.0, np.nan, 0.0])
    det = dets([(1, CAR, car(0, 0), 0.9), (1, CAR, car(5, -5), 0.8)])
    by = record(score(gt, det, region=REGION))["by_motion"]
    assert by["standing"] == {"gt": 2, "tp": 1, "missed": 1, "recall": 0.5}
    assert by["moving"] == {"gt": 1, "tp": 1, "missed": 0, "recall": 1.0}
    assert by["unknown"] == {"gt": 1, "tp": 0, "missed": 1, "recall": 0.0}
    ped = record(score(gt, det, region=REGION), cls="pedestrian")["by_motion"]
    assert ped == {"standing": {"gt": 0, "tp": 0, "missed": 0, "recall": None},
                   "moving": {"gt": 0, "tp": 0, "missed": 0, "recall": None}}


def test_a_box_on_a_bin_edge_belongs_to_the_bin_that_starts_there():
    # Bins are [lo, hi): a car centred exactly 30 m from the sensor is in 30-inf, not in
    # 0-30, both in score's bins (from the frame's nearest sensor) and in evaluate's
    # (from a given sensor position). The rule is one function (average_precision.in_bin);
    # written as (lo, hi] anywhere, this fails.
    from rls_addon.core.evaluate.average_precision import evaluate

    gt = truth([(1, 1, CAR, car(30, 0), 50)], at=(0.0, 0.0, 6.0))
    det = dets([(1, CAR, car(30, 0), 0.9)])
    r = score(gt, det, distance_bins=(0, 30, math.inf), iou_thresholds=(0.5,), kinds="bev")
    near, far = (b["bev"]["0.5"] for b in r["classes"]["vehicle"]["bins"])
    assert (near["gt"], near["tp"], far["gt"], far["tp"]) == (0, 0, 1, 1)
    e = evaluate(gt.boxes, det, iou_thresholds=(0.5,), kinds="bev", classes=[CAR],
                 distance_bins=(0, 30, math.inf), sensor_xy=(0.0, 0.0))
    near, far = (b["bev"]["0.5"] for b in e["classes"]["vehicle"]["bins"])
    assert (near["gt"], near["tp"], far["gt"], far["tp"]) == (0, 0, 1, 1)


def test_ground_truth_written_by_rls_as_detections_scores_one(tmp_path):
    sensor = pose(1.0, 2.0, 5.0, yaw=2.0, pitch=math.radians(8))
    root = kitti_dataset(tmp_path / "ds", sensor, frames=(1, 2))
    gt = read_ground_truth(root)
    write_detections(tmp_path / "det", gt.boxes, root)
    r = score(gt, read_detection_files(tmp_path / "det", dataset=root))
    for cls in ("vehicle", "pedestrian", "cyclist"):
        for kind in ("bev", "3d"):
            for t in ("0.3", "0.5", "0.7"):
                rec = record(r, kind, t, cls)
                assert (rec["ap_r40"], rec["ap_voc"], rec["fp"]) == (1.0, 1.0, 0), (cls, kind, t)
    # the hidden car (0 points) is don't-care: its detection dropped
    assert record(r)["ignored"] == 2 and record(r)["gt"] == 2


def test_frames_text():
    assert frames_text([3, 1, 2, 7, 9, 10]) == "1-3, 7, 9-10"
    assert frames_text([]) == "none"


GT = truth([(1, 1, CAR, car(0, 0), 50)], frames=(1, 2))


@pytest.mark.parametrize("change, message", [
    (dict(detections=dets([(5, CAR, car(0, 0), 0.9), (7, CAR, car(0, 0), 0.9)])),
     r"detections for frames 5, 7 that the ground truth does not have \(it has frames "
     r"1-2\)"),
    (dict(detections=dets([(1, CAR, [0, 0, 0.75, math.nan, 2, 1.5, 0], 0.9)])),
     "box 0 of frame 1 has a NaN or infinite value"),
    (dict(detections=dets([(1, CAR, [0, 0, 0.75, 4, -2, 1.5, 0], 0.9)])),
     "box 0 of frame 1 has a size that is not positive"),
    (dict(classes=["vehicle", "truck2"]),
     "unknown class 'truck2': RLS evaluates vehicle, pedestrian, cyclist"),
    (dict(detections=DetectionFiles(Boxes.empty(), [], "kitti")),
     "the detections cover no frame"),
    (dict(region=[(100, 100), (110, 100), (110, 110)]),
     r"no ground-truth box with >= 5 points has its centre inside the region; of 1 boxes "
     r".* 0 are centred inside .* x 100 to 110, y 100 to 110 m"),
    (dict(region=[(0, 0), (1, 1), (2, 2)]), "region outline has zero area"),
    (dict(region=[(0, 0), (1, 1)]), "region outline needs at least 3 vertices"),
    (dict(min_points=-1), "min_points -1 must be a whole number >= 0"),
    (dict(distance_bins=(30, 10)), "distance bins .*increasing edges"),
    (dict(iou_thresholds=(0.5, 0)), "IoU threshold 0 must lie in"),
])
def test_each_bad_input_is_one_input_error(change, message):
    args = dict(truth=GT, detections=dets([(1, CAR, car(0, 0), 0.9)]))
    args.update(change)
    with pytest.raises(InputError, match=message):
        score(**args)


def test_an_empty_prediction_folder_is_refused(tmp_path):
    root = kitti_dataset(tmp_path / "ds", pose(), frames=(1,))
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty.*no detections found"):
        read_detection_files(tmp_path / "empty", dataset=root)
