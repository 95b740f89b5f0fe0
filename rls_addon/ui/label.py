"""The LiDAR Label panel: the semantic label an object's points get."""

import bpy

from ..blender.read_rules import GEOMETRY_TYPES
from ..blender.region import is_lob


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
