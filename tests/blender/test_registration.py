"""Register, unregister and register again must leave nothing behind."""

import bpy


def _state():
    return {
        "prop": hasattr(bpy.types.Object, "rls_lidar"),
        "add_op": hasattr(bpy.types, "OBJECT_OT_rls_add_lidar"),
        "scan_op": hasattr(bpy.types, "RLS_OT_scan_frame"),
        "panel": hasattr(bpy.types, "OBJECT_PT_rls_lidar"),
        "menu": any(getattr(f, "__name__", "") == "draw_add_menu"
                    for f in getattr(bpy.types.VIEW3D_MT_add.draw, "_draw_funcs", [])),
    }


def test_register_unregister_register_leaves_nothing(addon):
    assert all(_state().values())
    addon.unregister()
    assert not any(_state().values()), _state()
    addon.register()
    assert all(_state().values())
    # The menu entry is added once, not once per registration.
    funcs = bpy.types.VIEW3D_MT_add.draw._draw_funcs
    assert sum(getattr(f, "__name__", "") == "draw_add_menu" for f in funcs) == 1
