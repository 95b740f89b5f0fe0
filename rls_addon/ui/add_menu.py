"""The Add > LiDAR menu: presets by family, the InfraLOB, SUMO traffic.

Each device family of the registry (``core.device.families.FAMILIES``) gets a menu of
its own, made from its entry (label, icon) and kept in step with the registry
(``sync_family_menus``: a family added or removed while the extension is enabled gains
or loses its menu at once)."""

import bpy

from ..blender import preset_catalog
from ..core.device.families import FAMILIES

_MENUS = {}  # family id -> (its Family entry, its registered menu class)


def _family_menu(family):
    def draw(self, context):
        layout = self.layout
        layout.operator_context = "EXEC_REGION_WIN"
        for e in preset_catalog.catalog():
            if e.family == family.id:
                op = layout.operator("object.rls_add_lidar", text=e.name,
                                     icon="NONE" if e.builtin else "USER")
                op.preset = e.id

    return type(f"VIEW3D_MT_rls_add_{family.id}", (bpy.types.Menu,), {
        "bl_idname": f"VIEW3D_MT_rls_add_{family.id}",
        "bl_label": family.label,
        "bl_description": f"Add a {family.label} LiDAR",
        "draw": draw,
    })


def family_menus():
    """The registered family menus, in the registry's order."""
    return tuple(_MENUS[f.id][1] for f in FAMILIES if f.id in _MENUS)


def sync_family_menus():
    """Register one menu per family of ``FAMILIES`` and unregister those of families no
    longer there (or replaced by another entry of the same id)."""
    for fid, (fam, cls) in list(_MENUS.items()):
        if fid not in FAMILIES or FAMILIES.get(fid) is not fam:
            bpy.utils.unregister_class(cls)
            del _MENUS[fid]
    for fam in FAMILIES:
        if fam.id not in _MENUS:
            cls = _family_menu(fam)
            bpy.utils.register_class(cls)
            _MENUS[fam.id] = (fam, cls)


def unregister_family_menus():
    for _, cls in reversed(list(_MENUS.values())):
        bpy.utils.unregister_class(cls)
    _MENUS.clear()


class VIEW3D_MT_rls_add(bpy.types.Menu):
    """Add a LiDAR sensor with a device preset, or an InfraLOB region"""

    bl_idname = "VIEW3D_MT_rls_add"
    bl_label = "LiDAR"

    def draw(self, context):
        layout = self.layout
        present = {e.family for e in preset_catalog.catalog()}
        for fam in FAMILIES:
            if fam.id in present and fam.id in _MENUS:
                layout.menu(_MENUS[fam.id][1].bl_idname, icon=fam.icon)
        layout.separator()
        layout.operator("object.rls_add_infralob", icon="MESH_PLANE")
        layout.operator("rls.import_sumo_traffic", icon="AUTO")


def draw_add_menu(self, context):
    self.layout.menu(VIEW3D_MT_rls_add.bl_idname, icon="LIGHTPROBE_SPHERE")
