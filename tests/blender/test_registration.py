"""Register, unregister and register again must leave nothing behind."""

import bpy

NAMES = ("OBJECT_OT_rls_add_lidar", "OBJECT_OT_rls_add_infralob", "RLS_OT_scan_frame",
         "RLS_OT_scan_all", "RLS_OT_scan_range", "RLS_OT_batch_command", "RLS_OT_preview_color", "RLS_OT_compute_metrics",
         "RLS_OT_preset_apply", "RLS_OT_preset_save", "RLS_OT_preset_import",
         "RLS_OT_preset_import_calibration",
         "RLS_OT_preset_export", "RLS_OT_preset_delete", "RLS_OT_preset_refresh",
         "RLS_OT_import_sumo_traffic", "RLS_OT_export_dataset", "RLS_OT_import_sumo_network",
         "RLS_OT_generate_sumo_traffic", "RLS_OT_detect_evaluate", "SCENE_PT_rls_evaluate",
         "RLS_APRow", "RLS_EvaluationSettings",
         "OBJECT_PT_rls_lidar", "OBJECT_PT_rls_lidar_range", "OBJECT_PT_rls_lidar_motion",
         "OBJECT_PT_rls_lidar_output", "OBJECT_PT_rls_lidar_preview", "OBJECT_PT_rls_lidar_metrics",
         "OBJECT_PT_rls_infralob", "OBJECT_PT_rls_label", "RLS_PT_device_presets",
         "VIEW3D_MT_rls_add", "VIEW3D_MT_rls_add_spinning", "VIEW3D_MT_rls_add_mems",
         "VIEW3D_MT_rls_add_risley", "VIEW3D_MT_rls_add_custom",
         "RLS_LidarSettings", "RLS_SceneSettings")

PROPERTY_GROUPS = {"RLS_LidarSettings", "RLS_SceneSettings", "RLS_APRow", "RLS_EvaluationSettings"}


def _state():
    state = {
        "prop": hasattr(bpy.types.Object, "rls_lidar"),
        "scene_prop": hasattr(bpy.types.Scene, "rls"),
        "menu": any(getattr(f, "__name__", "") == "draw_add_menu"
                    for f in getattr(bpy.types.VIEW3D_MT_add.draw, "_draw_funcs", [])),
        "import_menu": any(getattr(f, "__name__", "") == "draw_import_menu" for f in
                           getattr(bpy.types.TOPBAR_MT_file_import.draw, "_draw_funcs", [])),
        "export_menu": any(getattr(f, "__name__", "") == "draw_export_menu" for f in
                           getattr(bpy.types.TOPBAR_MT_file_export.draw, "_draw_funcs", [])),
    }
    from rls_addon import registration, ui

    state["family_menus"] = len(ui.family_menus()) == 4
    state.update({c.__name__: c.is_registered for c in registration.CLASSES})
    state.update({n: hasattr(bpy.types, n) for n in NAMES if n not in PROPERTY_GROUPS})
    return state


def test_register_unregister_register_leaves_nothing(addon):
    from rls_addon import registration, ui

    menus = {c.__name__ for c in ui.family_menus()}  # one per device family, apart
    assert {c.__name__ for c in registration.CLASSES} | menus == set(NAMES)
    assert all(_state().values()), _state()
    addon.unregister()
    assert not any(_state().values()), _state()
    addon.register()
    assert all(_state().values())
    # The menu entry is added once, not once per registration.
    funcs = bpy.types.VIEW3D_MT_add.draw._draw_funcs
    assert sum(getattr(f, "__name__", "") == "draw_add_menu" for f in funcs) == 1
    # The operators work after re-registration.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "rls_lidar"):
        addon.register()
    assert bpy.ops.object.rls_add_lidar(preset="velodyne_vlp16") == {"FINISHED"}
    assert bpy.context.active_object.rls_lidar.preset == "velodyne_vlp16"
