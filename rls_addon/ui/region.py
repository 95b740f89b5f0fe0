"""The InfraLOB's panel and the metrics drawn in it and under the LiDAR panel."""

import bpy

from ..blender.region import is_lob
from ..blender.sensor import lidar_objects
from .lidar import _LidarPanel


def draw_metrics(layout, context):
    """The InfraLOB metric settings and the stored results (never computed here)."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    rs = context.scene.rls
    layout.prop(rs, "lob")
    col = layout.column(align=True)
    col.prop(rs, "metric_labels")
    col.prop(rs, "metric_disks")
    col.prop(rs, "metric_radius")
    col.prop(rs, "metric_cell")
    col.prop(rs, "metric_seed")
    layout.operator("rls.compute_metrics", icon="GRAPH")
    if not rs.has_metrics:
        return
    box = layout.box()
    box.label(text=f"{rs.metric_lob_name}: {rs.metric_points} points from {rs.metric_sensors}")
    grid = box.grid_flow(columns=2, align=True)
    grid.label(text="InfraD")
    grid.label(text=f"{rs.infra_d:.3f} pts/m²")
    grid.label(text="InfraNUC")
    grid.label(text=f"{rs.infra_nuc:.4f}")
    grid.label(text="Area")
    grid.label(text=f"{rs.metric_area:.1f} m²")
    if rs.metric_image is not None:
        box.template_icon(icon_value=layout.icon(rs.metric_image), scale=10.0)
        box.label(text=f"Density map: image '{rs.metric_image.name}' (north up)")


class OBJECT_PT_rls_lidar_metrics(_LidarPanel, bpy.types.Panel):
    bl_label = "InfraLOB Metrics"
    bl_parent_id = "OBJECT_PT_rls_lidar"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_metrics(self.layout, context)


class OBJECT_PT_rls_infralob(bpy.types.Panel):
    bl_label = "InfraLOB"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and is_lob(context.object)

    def draw(self, context):
        n = len(lidar_objects(context.scene))
        self.layout.label(text=f"Region of interest for {n} LiDAR(s) in the scene", icon="INFO")
        draw_metrics(self.layout, context)
