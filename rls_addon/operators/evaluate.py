"""*Detect and Evaluate*: RLS's roadside detector over a kitti dataset (every LiDAR in
it, fused), scored against the dataset's ground truth in the scene's InfraLOB, the AP
table shown in the panel. It runs what ``rls detect`` and ``rls evaluate`` run (their
settings objects and core calls, ``core/evaluate/runs.py``), so its detection files and
result JSON are theirs."""

import os

import bpy

from ..core.errors import InputError, RLSError
from ..core.evaluate.runs import (DetectSettings, EvaluateSettings, evaluate, kitti_roots,
                                  result_json, run_detection)
from .common import cancelled

RESULT_NAME = "evaluation.json"  # written into the detections folder


def default_detections(dataset):
    """DATASET_detections beside the dataset folder."""
    return os.path.normpath(dataset) + "_detections"


def region_of(context):
    """(outline, description) of the scene's InfraLOB as ``rls evaluate --lob
    SCENE.blend:NAME`` describes it, or an error naming what to do."""
    from ..blender.region import lob_polygon_world
    from ..blender.study import find_lob

    sc = context.scene
    lob = sc.rls.lob if sc.rls.lob is not None and sc.rls.lob.name in sc.objects else None
    lob = lob or find_lob(sc)
    where = os.path.basename(bpy.data.filepath) if bpy.data.filepath else sc.name
    return tuple(map(tuple, lob_polygon_world(lob))), f"{lob.name} in {where}"


def show_result(ev, result, path):
    """The panel's copy of ``result``: the summary line and a row per class, kind and
    IoU over the whole region."""
    g, d = result["ground_truth"], result["detections"]
    ev.summary = (f"{len(g['frames'])} frames of {', '.join(g['sensors'])}: {g['counted']} "
                  f"boxes counted, {d['boxes']} detections")
    ev.rows.clear()
    for name, c in result["classes"].items():
        for kind in result["kinds"]:
            for t in result["iou_thresholds"]:
                r = c["all"][kind][f"{t:g}"]
                row = ev.rows.add()
                row.name, row.kind, row.iou = name, kind.upper(), t
                row.ap_r40 = -1.0 if r["ap_r40"] is None else r["ap_r40"]
                row.ap_voc = -1.0 if r["ap_voc"] is None else r["ap_voc"]
                row.tp, row.fp, row.gt = r["tp"], r["fp"], r["gt"]
    ev.result_path = path
    ev.has_result = True


class RLS_OT_detect_evaluate(bpy.types.Operator):
    """Run RLS's roadside detector over the dataset (its LiDARs fused) and score it
    against the dataset's ground truth in the InfraLOB: AP per class and IoU (what rls
    detect, then rls evaluate, give)"""

    bl_idname = "rls.detect_evaluate"
    bl_label = "Detect and Evaluate"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if not context.scene.rls.evaluation.dataset:
            cls.poll_message_set("Choose a dataset (File > Export > RLS Dataset, KITTI)")
            return False
        return True

    def execute(self, context):
        from ..core.output.io.atomic import atomic_write_bytes
        from ..core.scan.frames import parse_frames

        ev = context.scene.rls.evaluation
        wm = context.window_manager
        dataset = os.path.normpath(bpy.path.abspath(ev.dataset))
        detections = (os.path.normpath(bpy.path.abspath(ev.detections)) if ev.detections
                      else default_detections(dataset))
        bar = {"on": False}

        def progress(i, n, frame):
            if not bar["on"]:
                wm.progress_begin(0, n)
                bar["on"] = True
            wm.progress_update(i)

        try:
            roots = kitti_roots(dataset)
            if not roots:
                raise InputError(f"{dataset} is not a kitti dataset (a folder per LiDAR with "
                                 "meta/): export one with File > Export > RLS Dataset, KITTI")
            frames = (parse_frames(ev.background_frames.strip(), None, "Background Frames")
                      if ev.background_frames.strip() else None)
            region, region_name = region_of(context) if ev.use_region else (None, None)
            run_detection(DetectSettings(tuple(str(r) for r in roots), detections, frames,
                                         None, ev.overwrite), progress)
            result = evaluate(EvaluateSettings(
                truth=(dataset,), detections=detections, dataset=str(roots[0]),
                region=region, region_name=region_name, min_points=ev.min_points))
            path = os.path.join(detections, RESULT_NAME)
            atomic_write_bytes(path, result_json(result), overwrite=True)
        except RLSError as exc:
            return cancelled(self, exc)
        finally:
            if bar["on"]:
                wm.progress_end()
        show_result(ev, result, path)
        for notice in result["notices"]:
            self.report({"INFO"}, notice)
        self.report({"INFO"}, f"{ev.summary}; result in {path}")
        return {"FINISHED"}


CLASSES = (RLS_OT_detect_evaluate,)
