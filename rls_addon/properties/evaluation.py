"""Detect and Evaluate (``Scene.rls.evaluation``): the dataset to run RLS's roadside
detector over, where its detections go, what counts, and the last result (draw() only
shows it)."""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, IntProperty,
                       StringProperty)


class RLS_APRow(bpy.types.PropertyGroup):
    """One line of the result: a class at an IoU threshold, BEV or 3D"""

    name: StringProperty(name="Class", description="The class scored")
    kind: StringProperty(name="Kind", description="BEV (bird's-eye view) or 3D overlap")
    iou: FloatProperty(name="IoU", description="The overlap a detection needs to match")
    ap_r40: FloatProperty(name="AP R40", default=-1.0,
                          description="KITTI's AP over 40 recall points (-1: no counted truth)")
    ap_voc: FloatProperty(name="AP VOC", default=-1.0,
                          description="VOC's all-point AP, as OpenCOOD (-1: no counted truth)")
    tp: IntProperty(name="TP", description="Detections that matched a counted box")
    fp: IntProperty(name="FP", description="Detections that matched nothing")
    gt: IntProperty(name="GT", description="Counted ground-truth boxes")


class RLS_EvaluationSettings(bpy.types.PropertyGroup):
    dataset: StringProperty(name="Dataset", subtype="DIR_PATH",
                            description="A kitti dataset folder (File > Export > RLS Dataset "
                                        "fills it in): every LiDAR in it is detected together "
                                        "and scored as one")
    detections: StringProperty(name="Detections", subtype="DIR_PATH",
                               description="Where the detection files go (empty: DATASET_"
                                           "detections beside the dataset)")
    background_frames: StringProperty(name="Background Frames",
                                      description="Frames to learn the background from, e.g. "
                                                  "1-20 (empty: every frame)")
    use_region: BoolProperty(name="In the InfraLOB", default=True,
                             description="Score boxes centred in the scene's InfraLOB (else "
                                         "everywhere)")
    min_points: IntProperty(name="Min Points", default=5, min=0,
                            description="Returns a ground-truth box needs to count")
    overwrite: BoolProperty(name="Replace Detections", default=False,
                            description="Replace detection files of an earlier run")
    # the last result (Detect and Evaluate fills them)
    has_result: BoolProperty(default=False, options={"HIDDEN"},
                             description="A result is shown below")
    summary: StringProperty(name="Summary", description="What was scored")
    result_path: StringProperty(name="Result", subtype="FILE_PATH",
                                description="The whole result as JSON (rls evaluate --out)")
    rows: CollectionProperty(type=RLS_APRow, name="AP",
                             description="AP per class and IoU threshold")
