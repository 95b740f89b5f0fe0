"""Everything the extension registers, in one place; unregistered in reverse order."""

import bpy

from . import operators, properties, ui
from .cli import main
from .core.device.families import FAMILIES
from .core.errors import RLSError

CLASSES = properties.CLASSES + operators.CLASSES + ui.CLASSES
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)
_state = {"cli": None}


def register():
    _register_classes()
    ui.sync_family_menus()
    FAMILIES.subscribe(_families_changed)
    properties.register_properties()
    _refresh_presets()
    bpy.types.VIEW3D_MT_add.append(ui.draw_add_menu)
    bpy.types.TOPBAR_MT_file_import.append(operators.roads.draw_import_menu)
    bpy.types.TOPBAR_MT_file_import.append(operators.traffic.draw_import_menu)
    bpy.types.TOPBAR_MT_file_export.append(operators.dataset.draw_export_menu)
    _state["cli"] = bpy.utils.register_cli_command("rls", blender_command)


def _refresh_presets():
    try:  # read the preset list now, so no panel or menu ever has to
        properties.refresh_preset_items()
    except RLSError as exc:
        print(f"rls: warning: {exc}")


def _families_changed(families):
    """A device family was added or removed: its menu, and the presets that name it."""
    ui.sync_family_menus()
    _refresh_presets()


def ensure_registered():
    """Register everything unless it is (the one place that asks)."""
    if not hasattr(bpy.types.Object, "rls_lidar"):
        register()


def blender_command(argv):
    """Handler of ``blender -b scene.blend -c rls ...``: the command line, told how to
    register the extension again (``rls demo`` resets Blender to its factory settings)."""
    return main(list(argv), prepare_blender=ensure_registered)


def unregister():
    if _state["cli"] is not None:
        bpy.utils.unregister_cli_command(_state["cli"])
        _state["cli"] = None
    bpy.types.TOPBAR_MT_file_export.remove(operators.dataset.draw_export_menu)
    bpy.types.TOPBAR_MT_file_import.remove(operators.traffic.draw_import_menu)
    bpy.types.TOPBAR_MT_file_import.remove(operators.roads.draw_import_menu)
    bpy.types.VIEW3D_MT_add.remove(ui.draw_add_menu)
    properties.unregister_properties()
    FAMILIES.unsubscribe(_families_changed)
    ui.unregister_family_menus()
    _unregister_classes()
