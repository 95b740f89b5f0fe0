"""Panels and menus. ``draw()`` only lays out properties and cached data: no scanning, no
file I/O, no preset loading (the preset list is an in-memory catalog refreshed by the
preset operators)."""

import textwrap

import bpy

from .blender import preset_catalog
from .blender.extract import GEOMETRY_TYPES
from .blender.region import is_lob
from .blender.sensor import is_lidar, lidar_objects
from .core.casting import backend_status
from .core.device.presets import FAMILIES
from .properties import lidar_mode_items

FAMILY_ICONS = {"spinning": "LIGHTPROBE_SPHERE", "mems": "LIGHTPROBE_PLANE",
                "risley": "LIGHTPROBE_VOLUME", "custom": "FILE_TEXT"}


def _wrapped(layout, text, width=48):
    col = layout.column(align=True)
    for line in textwrap.wrap(text, width) or [""]:
        col.label(text=line)


# ---- Add menu ----------------------------------------------------------------------------

def _family_menu(family):
    def draw(self, context):
        layout = self.layout
        layout.operator_context = "EXEC_REGION_WIN"
        for e in preset_catalog.catalog():
            if e.family == family:
                op = layout.operator("object.rls_add_lidar", text=e.name,
                                     icon="NONE" if e.builtin else "USER")
                op.preset = e.id

    return type(f"VIEW3D_MT_rls_add_{family}", (bpy.types.Menu,), {
        "bl_idname": f"VIEW3D_MT_rls_add_{family}",
        "bl_label": preset_catalog.FAMILY_LABELS[family],
        "bl_description": f"Add a {preset_catalog.FAMILY_LABELS[family]} LiDAR",
        "draw": draw,
    })


FAMILY_MENUS = tuple(_family_menu(f) for f in FAMILIES)


class VIEW3D_MT_rls_add(bpy.types.Menu):
    """Add a LiDAR sensor with a device preset, or an InfraLOB region"""

    bl_idname = "VIEW3D_MT_rls_add"
    bl_label = "LiDAR"

    def draw(self, context):
        layout = self.layout
        present = {e.family for e in preset_catalog.catalog()}
        for fam, menu in zip(FAMILIES, FAMILY_MENUS):
            if fam in present:
                layout.menu(menu.bl_idname, icon=FAMILY_ICONS[fam])
        layout.separator()
        layout.operator("object.rls_add_infralob", icon="MESH_PLANE")
        layout.operator("rls.import_sumo_traffic", icon="AUTO")


def draw_add_menu(self, context):
    self.layout.menu(VIEW3D_MT_rls_add.bl_idname, icon="LIGHTPROBE_SPHERE")


# ---- device preset popover (in the LiDAR panel's header) ------------------------------------

class RLS_PT_device_presets(bpy.types.Panel):
    """Device presets: built-in (read-only) and user presets, all validated TOML data"""

    bl_label = "Device Presets"
    bl_space_type = "PROPERTIES"
    bl_region_type = "HEADER"
    bl_ui_units_x = 14

    def draw(self, context):
        layout = self.layout
        obj = context.object
        current = obj.rls_lidar.preset_id if obj is not None and is_lidar(obj) else None
        for fam, entries in preset_catalog.by_family():
            layout.label(text=preset_catalog.FAMILY_LABELS[fam], icon=FAMILY_ICONS[fam])
            col = layout.column(align=True)
            for e in entries:
                row = col.row(align=True)
                op = row.operator("rls.preset_apply", text=e.name, depress=e.id == current,
                                  icon="NONE" if e.builtin else "USER")
                op.preset = e.id
                if not e.builtin:
                    row.operator("rls.preset_delete", text="", icon="X").preset = e.id
        for err in preset_catalog.errors()[:3]:
            layout.label(text=err[-60:], icon="ERROR")
        layout.separator()
        row = layout.row(align=True)
        row.operator("rls.preset_save", text="Save", icon="ADD")
        row.operator("rls.preset_import", text="Import", icon="IMPORT")
        row.operator("rls.preset_import_calibration", text="Calibration", icon="IMPORT")
        row.operator("rls.preset_export", text="Export", icon="EXPORT")
        row.operator("rls.preset_refresh", text="", icon="FILE_REFRESH")


# ---- LiDAR panel ------------------------------------------------------------------------------

class _LidarPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and is_lidar(context.object)


class OBJECT_PT_rls_lidar(_LidarPanel, bpy.types.Panel):
    bl_label = "LiDAR"

    def draw_header_preset(self, context):
        e = preset_catalog.entry(context.object.rls_lidar.preset_id)
        self.layout.popover(panel="RLS_PT_device_presets", icon="PRESET",
                            text=e.name if e else "Presets")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        layout.prop(s, "preset")
        e = preset_catalog.entry(s.preset_id)
        box = layout.box()
        if e is None:
            box.label(text=f"Unknown preset '{s.preset_id}': choose a device", icon="ERROR")
        else:
            kind = "built-in" if e.builtin else "user preset"
            box.label(text=f"{preset_catalog.FAMILY_LABELS.get(e.family, e.family)}, {kind}",
                      icon="INFO")
            _wrapped(box, f"Source: {e.source}")
        row = layout.row(heading="Field of View")
        row.prop(s, "show_fov", text="")
        sub = row.row()
        sub.active = s.show_fov
        sub.prop(s, "fov_length", text="")
        col = layout.column(align=True)
        col.operator("rls.scan_frame", icon="RENDER_STILL")
        col.operator("rls.scan_all", icon="RENDERLAYERS")
        rs = context.scene.rls
        box = layout.box()
        box.prop(rs, "use_scene_range")
        sub = box.column(align=True)
        sub.active = not rs.use_scene_range
        sub.prop(rs, "frame_start")
        sub.prop(rs, "frame_end")
        sub.prop(rs, "frame_step")
        box.prop(rs, "range_all_lidars")
        op = box.operator("rls.scan_range", icon="RENDER_ANIMATION")
        op.use_scene_range = rs.use_scene_range
        op.frame_start, op.frame_end, op.frame_step = rs.frame_start, rs.frame_end, rs.frame_step
        op.all_lidars = rs.range_all_lidars
        box.operator("rls.batch_command", icon="CONSOLE").all_lidars = rs.range_all_lidars


class OBJECT_PT_rls_lidar_range(_LidarPanel, bpy.types.Panel):
    bl_label = "Range and Noise"
    bl_parent_id = "OBJECT_PT_rls_lidar"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        for use, value, heading in (("use_min_range", "min_range", "Min Range"),
                                    ("use_max_range", "max_range", "Max Range")):
            row = layout.row(heading=heading)
            row.prop(s, use, text="")
            sub = row.row()
            sub.active = getattr(s, use)
            sub.prop(s, value, text="")
        col = layout.column(heading="Effects")
        col.prop(s, "noise")
        col.prop(s, "dropout")
        row = layout.row(heading="Noise Sigma")
        row.active = s.noise
        row.prop(s, "use_noise_sigma", text="")
        sub = row.row()
        sub.active = s.use_noise_sigma
        sub.prop(s, "noise_sigma", text="")
        layout.prop(s, "seed")
        layout.prop(s, "detection")
        layout.prop(s, "footprint")
        row = layout.row()
        row.active = s.footprint != "off"
        row.prop(s, "return_mode")
        row = layout.row(heading="Rotation")
        row.prop(s, "use_rotation_hz", text="")
        sub = row.row()
        sub.active = s.use_rotation_hz
        sub.prop(s, "rotation_hz", text="")
        if len(lidar_mode_items(s, context)) > 1:
            layout.prop(s, "lidar_mode")
        layout.prop(s, "weather")
        if s.weather == "fog":
            layout.prop(s, "fog_visibility")
        elif s.weather in ("rain", "snow"):
            layout.prop(s, "precipitation_rate")
            if s.weather == "snow":
                layout.prop(s, "snow_type")


class OBJECT_PT_rls_lidar_motion(_LidarPanel, bpy.types.Panel):
    bl_label = "Motion and Ghosts"
    bl_parent_id = "OBJECT_PT_rls_lidar"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        layout.prop(s, "motion")
        sub = layout.row()
        sub.active = s.motion == "substeps"
        sub.prop(s, "substeps")
        row = layout.row(heading="Sweep Start")
        row.prop(s, "use_sweep_start", text="")
        sub = row.row()
        sub.active = s.use_sweep_start
        sub.prop(s, "sweep_start", text="")
        layout.prop(s, "ghosting")
        layout.prop(s, "backend")
        layout.label(text=backend_status(s.backend)[1], icon="INFO")  # cached per choice


class OBJECT_PT_rls_lidar_output(_LidarPanel, bpy.types.Panel):
    bl_label = "Output"
    bl_parent_id = "OBJECT_PT_rls_lidar"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        layout.prop(s, "output_dir")
        layout.prop(s, "file_format")
        layout.prop(s, "name_template")
        layout.prop(s, "frame_space")
        layout.prop(s, "point_type")
        col = layout.column(heading="Fields", align=True)
        col.active = s.point_type == "rls"  # a vendor's point type has its own fields
        col.prop(s, "fields")
        row = layout.row()
        row.active = s.file_format == "las"
        row.prop(s, "crs")
        layout.prop(s, "ground_truth")
        sub = layout.row()
        sub.active = s.ground_truth
        sub.prop(s, "object_classes")


class OBJECT_PT_rls_lidar_preview(_LidarPanel, bpy.types.Panel):
    bl_label = "Preview"
    bl_parent_id = "OBJECT_PT_rls_lidar"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        layout.prop(s, "preview_color")
        layout.operator("rls.preview_color", icon="COLOR").attribute = s.preview_color
        layout.label(text="Colours show in Material Preview and Rendered shading", icon="INFO")


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


class OBJECT_PT_rls_label(bpy.types.Panel):
    """The semantic label this object's LiDAR points get"""

    bl_label = "LiDAR Label"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        obj = context.object
        return (obj is not None and obj.type in GEOMETRY_TYPES and not is_lob(obj)
                and not obj.get("rls_preview") and not obj.get("rls_fov"))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.object.rls_lidar, "label")


CLASSES = FAMILY_MENUS + (
    VIEW3D_MT_rls_add,
    RLS_PT_device_presets,
    OBJECT_PT_rls_lidar,
    OBJECT_PT_rls_lidar_range,
    OBJECT_PT_rls_lidar_motion,
    OBJECT_PT_rls_lidar_output,
    OBJECT_PT_rls_lidar_preview,
    OBJECT_PT_rls_lidar_metrics,
    OBJECT_PT_rls_infralob,
    OBJECT_PT_rls_label,
)
