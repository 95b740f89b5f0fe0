"""Live coverage's properties (``Scene.rls_live``): its timing (the debounce and the
budget) and what the last update showed (``draw()`` only shows them). Whether it is on
is the running session's (``blender.live``), not saved in the file. The region and the
metric settings are the Metrics panel's (``Scene.rls``)."""

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty


def _is_live(self):
    from ..blender.live import is_live

    return is_live(self.id_data)


class RLS_LiveSettings(bpy.types.PropertyGroup):
    active: BoolProperty(name="Live", get=_is_live,
                         description="Live coverage is on in this scene (not saved in the file)")
    debounce_ms: FloatProperty(name="Still For", default=40.0, min=0.0, soft_max=500.0,
                               description="A LiDAR is rescanned once it has been still for "
                                           "this many milliseconds")
    budget_ms: FloatProperty(name="Budget", default=150.0, min=1.0, soft_max=2000.0,
                             description="The longest an update may hold Blender (its "
                                         "scans and showing, ms); a scene over it twice in "
                                         "a row is updated on demand")
    status: StringProperty(name="Status", default="", description="What live coverage is doing")
    on_demand: BoolProperty(name="On Demand", default=False,
                            description="Updates took longer than the budget: coverage is "
                                        "updated on demand (Update Coverage)")
    infra_d: FloatProperty(name="InfraD", default=0.0, precision=3,
                           description="Points per square metre in the InfraLOB, live")
    infra_nuc: FloatProperty(name="InfraNUC", default=float("nan"), precision=4,
                             description="Non-uniformity of the points in the InfraLOB, live")
    points: IntProperty(name="Points", default=0, description="Points counted in the InfraLOB")
    scale: FloatProperty(name="Map Scale", default=0.0,
                         description="Points per m² of the map's yellow (its densest cell)")
    sensors: StringProperty(name="Sensors", default="",
                            description="The LiDARs whose points are counted")
    latency_ms: FloatProperty(name="Latency", default=0.0,
                              description="The last update: from the last change to shown (ms)")
    work_ms: FloatProperty(name="Work", default=0.0,
                           description="The last update: scanning and showing (ms)")
    scans: IntProperty(name="Scans", default=0, description="Scans live coverage made")
    superseded: IntProperty(name="Superseded", default=0,
                            description="Scans a newer change made useless")
