"""Live coverage in the InfraLOB's and the LiDAR's panels: the toggle, the timing, and
the numbers of the last update (``draw()`` only shows stored values)."""

import math

import bpy

from .lidar import _LidarPanel


def draw_live(layout, context):
    p = context.scene.rls_live
    row = layout.row(align=True)
    row.operator("rls.live_coverage", text="Live Coverage", icon="REC", depress=p.active)
    if p.active:  # on demand: the button the user now needs, with its name
        row.operator("rls.live_update", text="Update Coverage" if p.on_demand else "",
                     icon="FILE_REFRESH")
    col = layout.column(align=True)
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(p, "debounce_ms")
    col.prop(p, "budget_ms")
    if not p.active:
        return
    box = layout.box()
    box.label(text=p.status or "live", icon="ERROR" if p.on_demand else "INFO")
    grid = box.grid_flow(columns=2, align=True)
    grid.label(text="InfraD")
    grid.label(text=f"{p.infra_d:.3f} pts/m²")
    grid.label(text="InfraNUC")
    grid.label(text=f"{p.infra_nuc:.4f}" if math.isfinite(p.infra_nuc) else "-")
    grid.label(text="Points")
    grid.label(text=f"{p.points:,}")
    grid.label(text="Last update")
    grid.label(text=f"{p.latency_ms:.0f} ms ({p.work_ms:.0f} ms work)")
    grid.label(text="Scans")
    grid.label(text=f"{p.scans} ({p.superseded} superseded)")
    box.label(text=f"Map: 0 (purple) to {p.scale:.3g} pts/m² (yellow), white: no returns")


class OBJECT_PT_rls_live(bpy.types.Panel):
    bl_label = "Live Coverage"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_rls_infralob"

    def draw(self, context):
        draw_live(self.layout, context)


class OBJECT_PT_rls_lidar_live(_LidarPanel, bpy.types.Panel):
    bl_label = "Live Coverage"
    bl_parent_id = "OBJECT_PT_rls_lidar"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_live(self.layout, context)


CLASSES = (
    OBJECT_PT_rls_live,
    OBJECT_PT_rls_lidar_live,
)
