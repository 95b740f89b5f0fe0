"""The Detect and Evaluate panel and its button in the bpy module: what it asks for,
its errors, and the result table it draws from stored properties. That the button
writes what rls detect and rls evaluate write: tests/cli/test_ui_matches_cli.py."""

from types import SimpleNamespace

import pytest

from .conftest import bpy
from .test_ui_panels import _draw, no_heavy_work  # noqa: F401 (fixture)


def test_needs_a_kitti_dataset(scene, tmp_path):
    with pytest.raises(RuntimeError, match="Choose a dataset"):
        bpy.ops.rls.detect_evaluate()
    scene.rls.evaluation.dataset = str(tmp_path)
    with pytest.raises(RuntimeError, match="not a kitti dataset .*File > Export > RLS Dataset"):
        bpy.ops.rls.detect_evaluate()
    assert not scene.rls.evaluation.has_result


def test_panel_draws_the_result_table(scene, no_heavy_work):  # noqa: F811
    from rls_addon import ui
    from rls_addon.operators.evaluate import show_result

    def counts(tp, fp, gt, ap):
        return {"tp": tp, "fp": fp, "gt": gt, "ap_r40": ap, "ap_voc": ap}

    result = {"ground_truth": {"frames": [1, 2], "sensors": ["A", "B"], "counted": 9},
              "detections": {"boxes": 8}, "kinds": ["bev", "3d"], "iou_thresholds": [0.5],
              "classes": {"vehicle": {"all": {"bev": {"0.5": counts(7, 1, 9, 0.75)},
                                              "3d": {"0.5": counts(6, 2, 9, 0.5)}}},
                          "cyclist": {"all": {"bev": {"0.5": counts(0, 0, 0, None)},
                                              "3d": {"0.5": counts(0, 0, 0, None)}}}}}
    ev = scene.rls.evaluation
    show_result(ev, result, "/x/evaluation.json")
    assert [(r.name, r.kind, r.tp) for r in ev.rows] == [
        ("vehicle", "BEV", 7), ("vehicle", "3D", 6), ("cyclist", "BEV", 0), ("cyclist", "3D", 0)]
    no_heavy_work()
    log = _draw(ui.SCENE_PT_rls_evaluate, SimpleNamespace(scene=scene))
    labels = [kw.get("text", "") for name, _, kw in log if name == "label"]
    assert "2 frames of A, B: 9 boxes counted, 8 detections" in labels
    assert ["vehicle", "BEV 0.5", "0.750", "0.750", "7", "1", "9"] == labels[
        labels.index("vehicle"):labels.index("vehicle") + 7]
    assert labels.count("-") == 4  # cyclist: no counted truth, AP undefined
    assert ("rls.detect_evaluate",) in [a for n, a, _ in log if n == "operator"]
