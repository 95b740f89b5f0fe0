"""Operators that add objects: a LiDAR (*Add > LiDAR*) and an InfraLOB region."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty

from ..blender.lidars import new_lidar
from ..blender.region import LOB_PROPERTY
from ..blender.sensor import DEFAULT_PRESET
from ..properties import preset_items
from .common import _select_only


class OBJECT_OT_rls_add_lidar(bpy.types.Operator):
    """Add a LiDAR sensor at the 3D cursor (its X axis looks forward, Z up)"""

    bl_idname = "object.rls_add_lidar"
    bl_label = "LiDAR"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Device", items=preset_items,
                         description="Device preset of the new LiDAR")
    show_fov: BoolProperty(name="Show Field of View", default=True,
                           description="Outline the device's field of view in the viewport")

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to add a LiDAR")
            return False
        return True

    def execute(self, context):
        obj = new_lidar(context.scene, "LiDAR", self.preset or DEFAULT_PRESET,
                        context.scene.cursor.location, collection=context.collection,
                        show_fov=self.show_fov, exact_name=False)
        _select_only(context, obj)
        return {"FINISHED"}


class OBJECT_OT_rls_add_infralob(bpy.types.Operator):
    """Add an InfraLOB: a flat rectangle on the ground marking the region the placement
    metrics (InfraD, InfraNUC) are computed over"""

    bl_idname = "object.rls_add_infralob"
    bl_label = "InfraLOB Region"
    bl_options = {"REGISTER", "UNDO"}

    size_x: FloatProperty(name="Size X", default=20.0, min=0.1, unit="LENGTH",
                          description="Length of the region along its X axis")
    size_y: FloatProperty(name="Size Y", default=30.0, min=0.1, unit="LENGTH",
                          description="Length of the region along its Y axis")

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to add a region")
            return False
        return True

    def execute(self, context):
        hx, hy = self.size_x / 2, self.size_y / 2
        mesh = bpy.data.meshes.new("InfraLOB")
        mesh.from_pydata([(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)], [], [(0, 1, 2, 3)])
        mesh.update()
        obj = bpy.data.objects.new("InfraLOB", mesh)
        obj[LOB_PROPERTY] = True
        obj.location = context.scene.cursor.location
        obj.display_type = "WIRE"
        obj.hide_render = True
        obj.visible_shadow = False
        (context.collection or context.scene.collection).objects.link(obj)
        context.scene.rls.lob = obj
        _select_only(context, obj)
        return {"FINISHED"}


CLASSES = (
    OBJECT_OT_rls_add_lidar,
    OBJECT_OT_rls_add_infralob,
)
