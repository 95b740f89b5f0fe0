"""Operators: thin wrappers that read properties, call the Blender adapters and
report domain errors."""

import bpy
from bpy.props import BoolProperty, EnumProperty

from .blender.preview import show_points
from .blender.scan import save_scan, scan_lidar
from .blender.sensor import DEFAULT_PRESET, is_lidar, lidar_settings
from .core.errors import RLSError
from .properties import preset_items


class OBJECT_OT_rls_add_lidar(bpy.types.Operator):
    """Add a LiDAR sensor at the 3D cursor (its X axis looks forward, Z up)"""

    bl_idname = "object.rls_add_lidar"
    bl_label = "LiDAR"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Device", items=preset_items)

    def execute(self, context):
        obj = bpy.data.objects.new("LiDAR", None)
        obj.empty_display_type = "ARROWS"
        obj.empty_display_size = 0.5
        obj.location = context.scene.cursor.location
        context.collection.objects.link(obj)
        s = lidar_settings(obj)
        s.is_lidar = True
        s.preset = self.preset or DEFAULT_PRESET
        for o in context.view_layer.objects:
            o.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        return {"FINISHED"}


class RLS_OT_scan_frame(bpy.types.Operator):
    """Scan the current frame with the active LiDAR and show the points"""

    bl_idname = "rls.scan_frame"
    bl_label = "Scan Frame"
    bl_options = {"REGISTER"}

    write: BoolProperty(name="Write File", default=True,
                        description="Write the point cloud and its sidecar to the output folder")
    preview: BoolProperty(name="Preview", default=True,
                          description="Show the points as an object in the scene")

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or not is_lidar(obj):
            cls.poll_message_set("Select a LiDAR object (Add > LiDAR) to scan")
            return False
        return True

    def execute(self, context):
        scene, obj = context.scene, context.active_object
        s = lidar_settings(obj)
        frame = scene.frame_current
        try:
            result, info = scan_lidar(context.evaluated_depsgraph_get(), obj, frame)
            where = ""
            if self.write:
                out_dir = bpy.path.abspath(s.output_dir)
                path = save_scan(result, info, out_dir, s.name_template, s.file_format,
                                 scene.name, overwrite=True)
                where = f" to {path}"
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if self.preview:
            show_points(scene, obj, result.points, info["frame_space"], info["sensor_to_world"])
        for w in result.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"{len(result.points)} points from {result.rays} rays "
                              f"in {result.seconds:.2f} s{where}")
        return {"FINISHED"}


CLASSES = (OBJECT_OT_rls_add_lidar, RLS_OT_scan_frame)
