"""KITTI's official AP_R40 (``kitti_official.py``) against the figures OpenPCDet's own
``kitti_object_eval_python`` computed for fixed boxes (tests/fixtures/kitti_official/:
the boxes, the figures and how they were made; not the code)."""

import json
from pathlib import Path

import numpy as np
import pytest

from rls_addon.core.evaluate.average_precision import evaluate
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.kitti_official import class_frames, get_thresholds, kitti_r40
from rls_addon.core.evaluate.matching import pair_overlaps

CASES = json.loads((Path(__file__).resolve().parents[2] / "fixtures" / "kitti_official"
                    / "cases.json").read_text())["cases"]
CAR = 11


def boxes_of(case):
    """(gt Boxes, det Boxes, gt_ignore, det_ignore) of a fixture case, frames numbered."""
    gt, det, gi, di = [], [], [], []
    for k, f in enumerate(case["frames"]):
        for b, flag in zip(f["gt"], f["gt_ignore"]):
            gt.append((k, b))
            gi.append(flag)
        for b, s, flag in zip(f["det"], f["det_score"], f["det_ignore"]):
            det.append((k, b, s))
            di.append(flag)
    g = Boxes([r[0] for r in gt], [r[1] for r in gt], CAR, 1.0)
    d = Boxes([r[0] for r in det], [r[1] for r in det], CAR, [r[2] for r in det])
    return g, d, np.array(gi, bool), np.array(di, bool)


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
@pytest.mark.parametrize("kind", ["bev", "3d"])
def test_agrees_with_openpcdet_to_1e4(case, kind):
    g, d, gi, di = boxes_of(case)
    ov = pair_overlaps(d, g, kind)
    for t, want in case["openpcdet_ap_r40"][kind].items():
        got = kitti_r40(class_frames(ov, d, g, gi, di, CAR), float(t))
        assert got == pytest.approx(want, abs=1e-4), (case["name"], kind, t)
        # and as rls evaluate reports it, beside the textbook R40
        rec = evaluate(g, d, gi, di, iou_thresholds=[float(t)], kinds=kind,
                       classes=[CAR])["classes"]["vehicle"]["all"][kind][t]
        assert rec["ap_r40_kitti"] == pytest.approx(want, abs=1e-4)


def test_the_cases_hold_what_they_are_for():
    few = next(c for c in CASES if c["name"] == "fewer than 40 boxes")
    assert few["counted_boxes"] < 40
    # every box found, nothing false: the textbook R40 is 1, KITTI's leaves recall points
    # at 0 past its last true positive
    clean = next(c for c in CASES if c["name"] == "no false positives, few boxes")
    g, d, gi, di = boxes_of(clean)
    rec = evaluate(g, d, gi, di, iou_thresholds=[0.5], kinds="bev",
                   classes=[CAR])["classes"]["vehicle"]["all"]["bev"]["0.5"]
    assert rec["ap_r40"] >= 0.85 and rec["ap_r40_kitti"] < 0.2
    # a detection at IoU exactly 0.5: a hit with RLS's '>=', none with KITTI's '>'
    half = next(c for c in CASES if c["name"] == "iou exactly 0.5")
    g, d, gi, di = boxes_of(half)
    assert pair_overlaps(d, g, "bev").iou.max() < 1 and 0.5 in pair_overlaps(d, g, "bev").iou
    rec = evaluate(g, d, gi, di, iou_thresholds=[0.5], kinds="bev",
                   classes=[CAR])["classes"]["vehicle"]["all"]["bev"]["0.5"]
    assert rec["tp"] == 2 and rec["ap_r40_kitti"] == 0.0


def test_threshold_sampling_keeps_the_last_true_positive():
    """get_thresholds walks the true positives' scores: with 4 boxes and 4 hits every
    score is a threshold, the last included; with 100 boxes and 3 hits, 3."""
    assert get_thresholds([0.9, 0.5, 0.7, 0.2], 4) == [0.9, 0.7, 0.5, 0.2]
    assert get_thresholds([0.3, 0.2, 0.1], 100)[-1] == 0.1
    assert kitti_r40([(np.zeros((0, 1)), [1], [], [])], 0.5) is None  # nothing counted
