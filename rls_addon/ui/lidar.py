"""The LiDAR panel (Object properties) and its sub-panels, and the device preset popover
in its header."""

import bpy

from ..blender import preset_catalog
from ..blender.sensor import is_lidar
from ..core.casting import backend_status
from ..properties import lidar_mode_items
from .common import wrapped


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
            layout.label(text=fam.label, icon=fam.icon)
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

SOURCE_PEEK = 40  # characters of a preset's source shown while its fold is closed


def draw_source(layout, source):
    """A preset's source (8 to 36 lines wrapped for the shipped presets, once always
    shown) folded under a one-line header that shows its start; open, the whole text.
    Blender keeps the fold's state (a layout panel, Blender 4.1 on)."""
    header, body = layout.panel("rls_preset_source", default_closed=True)
    peek = source if len(source) <= SOURCE_PEEK else source[:SOURCE_PEEK].rstrip() + "..."
    header.label(text=f"Source: {peek}")
    if body is not None:
        wrapped(body, source)


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
            box.label(text=f"{preset_catalog.family_label(e.family)}, {kind}",
                      icon="INFO")
            draw_source(box, e.source)
        row = layout.row(heading="Field of View")
        row.prop(s, "show_fov", text="")
        sub = row.row()
        sub.active = s.show_fov
        sub.prop(s, "fov_length", text="")
        rs = context.scene.rls
        col = layout.column(align=True)
        col.operator("rls.scan_frame", icon="RENDER_STILL").overwrite = rs.overwrite
        col.operator("rls.scan_all", icon="RENDERLAYERS").overwrite = rs.overwrite
        col.prop(rs, "overwrite")
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
        op.overwrite = rs.overwrite
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
