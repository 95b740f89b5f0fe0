"""Everything the extension registers, in one place; unregistered in reverse order."""

import bpy

from . import operators, properties, ui
from .cli import blender_command

CLASSES = properties.CLASSES + operators.CLASSES + ui.CLASSES
_state = {"cli": None}


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    properties.register_properties()
    bpy.types.VIEW3D_MT_add.append(ui.draw_add_menu)
    _state["cli"] = bpy.utils.register_cli_command("rls", blender_command)


def unregister():
    if _state["cli"] is not None:
        bpy.utils.unregister_cli_command(_state["cli"])
        _state["cli"] = None
    bpy.types.VIEW3D_MT_add.remove(ui.draw_add_menu)
    properties.unregister_properties()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
