"""Panels and menus. ``draw()`` only lays out properties: no scanning, no file I/O."""

import bpy

from .blender.sensor import is_lidar


class OBJECT_PT_rls_lidar(bpy.types.Panel):
    bl_label = "LiDAR"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and is_lidar(context.object)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.object.rls_lidar
        layout.prop(s, "preset")
        col = layout.column(heading="Effects")
        col.prop(s, "noise")
        col.prop(s, "dropout")
        row = layout.row(heading="Range")
        row.prop(s, "use_max_range", text="")
        sub = row.row()
        sub.active = s.use_max_range
        sub.prop(s, "max_range", text="")
        layout.prop(s, "seed")
        layout.prop(s, "frame_space")
        layout.prop(s, "output_dir")
        layout.prop(s, "file_format")
        layout.prop(s, "name_template")
        layout.operator("rls.scan_frame", icon="RENDER_STILL")


def draw_add_menu(self, context):
    self.layout.operator("object.rls_add_lidar", text="LiDAR", icon="LIGHTPROBE_SPHERE")


CLASSES = (OBJECT_PT_rls_lidar,)
