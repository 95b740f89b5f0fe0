"""The Placement Study panel under the InfraLOB: the settings of ``rls study``, the Run
button, and the last study's answer (the markers' colouring, the table as a sortable
list, the charts). ``draw()`` only lays out properties and stored results."""

import math

import bpy
from bpy.props import EnumProperty

from ..core.study.answer import table_order

SORT_ITEMS = [("k", "k", "By the number of sensors, then InfraD"),
              ("sensors", "Sensors", "By the sensors' names"),
              ("infra_d", "InfraD", "Densest first"),
              ("infra_nuc", "InfraNUC", "Most uniform first"),
              ("visibility", "Visibility", "Best seen traffic first"),
              ("ap", "AP", "Best detection first")]


def _num(v, fmt):
    return format(v, fmt) if math.isfinite(v) else "-"


class RLS_UL_study_rows(bpy.types.UIList):
    """The study's table: every candidate and each larger k's Pareto front and best set
    (every set in the report's placements.csv)"""

    sort_by: EnumProperty(name="Sort By", items=SORT_ITEMS, default="k",
                          description="Column the table is sorted by (scores best first)")

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname,
                  index):
        row = layout.row(align=True)
        split = row.split(factor=0.1)
        split.label(text=str(item.k))
        split = split.split(factor=0.5)
        mark = "SOLO_ON" if item.best else ("KEYFRAME" if item.pareto else "BLANK1")
        split.label(text=item.sensors, icon=mark)
        cols = split.row(align=True)
        cols.label(text=_num(item.infra_d, ".2f"))
        cols.label(text=_num(item.infra_nuc, ".3f"))
        cols.label(text=_num(item.visibility, ".2f"))
        cols.label(text=_num(item.ap, ".2f"))

    def draw_filter(self, context, layout):
        row = layout.row(align=True)
        row.prop(self, "filter_name", text="")
        row.prop(self, "sort_by", text="")
        row.prop(self, "use_filter_sort_reverse", text="", icon="SORT_DESC")

    def filter_items(self, context, data, propname):
        rows = getattr(data, propname)
        helper = bpy.types.UI_UL_list
        flags = (helper.filter_items_by_name(self.filter_name, self.bitflag_filter_item, rows,
                                             "sensors") if self.filter_name else [])
        order = table_order(rows, self.sort_by)
        neworder = [0] * len(rows)
        for position, i in enumerate(order):
            neworder[i] = position
        return flags, neworder


class OBJECT_PT_rls_study(bpy.types.Panel):
    bl_label = "Placement Study"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_rls_infralob"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        p = context.scene.rls_study
        layout.prop(p, "device")
        col = layout.column(align=True)
        col.prop(p, "k")
        col.prop(p, "pitches")
        col.prop(p, "yaws")
        col.prop(p, "yaw_mode")
        layout.prop(p, "mounts_from")
        layout.prop(p, "use_grid")
        if p.use_grid:
            col = layout.column(align=True)
            col.prop(p, "grid_step")
            col.prop(p, "grid_heights")
            col.prop(p, "grid_margin")
        col = layout.column(align=True)
        col.prop(p, "traffic")
        col.prop(p, "evaluate")
        layout.prop(p, "output_dir")
        if p.output_dir:
            layout.prop(p, "overwrite")
        layout.operator("rls.study", icon="VIEWZOOM")
        if not p.has_result:
            return
        box = layout.box()
        box.label(text=p.summary or "Study", icon="INFO")
        box.prop(p, "color_by")
        box.label(text=p.color_range)
        head = box.row()
        head.label(text="k, sensors (best: star, Pareto front: key), InfraD, InfraNUC, "
                        "visibility, AP")
        box.template_list("RLS_UL_study_rows", "", p, "rows", p, "row_index", rows=8)
        box.prop(p, "chart")
        if p.chart is not None:
            box.template_icon(icon_value=layout.icon(p.chart), scale=10.0)


class OBJECT_PT_rls_study_options(bpy.types.Panel):
    bl_label = "Scan and Region"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_rls_study"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        p = context.scene.rls_study
        col = layout.column(align=True)
        for name in ("labels", "disks", "radius", "disk_seed", "disk_placement", "cell"):
            col.prop(p, name)
        col = layout.column(align=True)
        for name in ("seed", "noise", "dropout", "keep_traffic", "roll", "shared_mounts",
                     "exhaustive_limit", "min_points", "backend"):
            col.prop(p, name)


CLASSES = (
    RLS_UL_study_rows,
    OBJECT_PT_rls_study,
    OBJECT_PT_rls_study_options,
)
