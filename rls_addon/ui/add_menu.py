"""The Add > LiDAR menu: presets by family, the InfraLOB, SUMO traffic."""

import bpy

from ..blender import preset_catalog
from ..core.device.presets import FAMILIES
from .common import FAMILY_ICONS


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
