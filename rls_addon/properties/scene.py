"""The scene's properties (``Scene.rls``): the frame range to scan, the InfraLOB metric
settings and the last metrics computed; Detect and Evaluate's (``evaluation.py``)."""

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..blender.region import is_lob
from .evaluation import RLS_EvaluationSettings


def _lob_poll(self, obj):
    return is_lob(obj)


class RLS_SceneSettings(bpy.types.PropertyGroup):
    frame_start: IntProperty(name="Start", default=1, description="First frame to scan")
    frame_end: IntProperty(name="End", default=10, description="Last frame to scan")
    frame_step: IntProperty(name="Step", default=1, min=1, description="Scan every Nth frame")
    use_scene_range: BoolProperty(name="Scene Frame Range", default=True,
                                  description="Scan the scene's frame range")
    range_all_lidars: BoolProperty(name="All LiDARs", default=False,
                                   description="Scan the frame range with every LiDAR in the scene")
    overwrite: BoolProperty(name="Overwrite Files", default=False,
                            description="Let the scan buttons replace files of earlier scans "
                                        "(without it they refuse, as rls scan does)")
    lob: PointerProperty(name="InfraLOB", type=bpy.types.Object, poll=_lob_poll,
                         description="Region of interest for the placement metrics")
    metric_labels: StringProperty(name="Labels", default="road,sidewalk",
                                  description="Labels of the points counted (names or ids, comma separated)")
    metric_disks: IntProperty(name="Disks", default=6000, min=1, soft_max=50000,
                              description="Random disks for InfraNUC")
    metric_radius: FloatProperty(name="Disk Radius", default=0.7, min=0.01, unit="LENGTH",
                                 description="Radius of the InfraNUC disks")
    metric_cell: FloatProperty(name="Map Cell", default=1.0, min=0.05, unit="LENGTH",
                               description="Cell size of the density map")
    metric_seed: IntProperty(name="Seed", default=0, min=0,
                             description="Seed of the random disk placement")
    # results of the last rls.compute_metrics (draw() only shows them)
    has_metrics: BoolProperty(default=False, options={"HIDDEN"},
                              description="Metrics have been computed (results below)")
    infra_d: FloatProperty(name="InfraD", default=0.0, precision=3,
                           description="Points per square metre in the InfraLOB")
    infra_nuc: FloatProperty(name="InfraNUC", default=0.0, precision=4,
                             description="Non-uniformity: standard deviation of normalised disk counts")
    metric_points: IntProperty(name="Points", default=0,
                               description="Points counted in the InfraLOB")
    metric_area: FloatProperty(name="Area", default=0.0, unit="AREA",
                               description="Area of the InfraLOB")
    metric_lob_name: StringProperty(name="Region", default="",
                                    description="The InfraLOB the metrics were computed over")
    metric_sensors: StringProperty(name="Sensors", default="",
                                   description="The LiDARs whose points were counted")
    metric_image: PointerProperty(name="Density Map", type=bpy.types.Image,
                                  description="Image of points per square metre in the InfraLOB")
    evaluation: PointerProperty(type=RLS_EvaluationSettings, name="Detect and Evaluate",
                                description="RLS's detector over a dataset, scored")
