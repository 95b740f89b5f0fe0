"""Panels and menus, a module per concern. ``draw()`` only lays out properties and cached
data: no scanning, no file I/O, no preset loading (the preset list is an in-memory catalog
refreshed by the preset operators)."""

from .add_menu import (VIEW3D_MT_rls_add, draw_add_menu, family_menus, sync_family_menus,
                       unregister_family_menus)
from .evaluate import SCENE_PT_rls_evaluate
from .label import OBJECT_PT_rls_label
from .lidar import (OBJECT_PT_rls_lidar, OBJECT_PT_rls_lidar_motion, OBJECT_PT_rls_lidar_output,
                    OBJECT_PT_rls_lidar_preview, OBJECT_PT_rls_lidar_range, RLS_PT_device_presets)
from .region import OBJECT_PT_rls_infralob, OBJECT_PT_rls_lidar_metrics

# The family menus are registered apart, one per device family (add_menu.sync_family_menus)
CLASSES = (
    VIEW3D_MT_rls_add,
    RLS_PT_device_presets,
    OBJECT_PT_rls_lidar,
    OBJECT_PT_rls_lidar_range,
    OBJECT_PT_rls_lidar_motion,
    OBJECT_PT_rls_lidar_output,
    OBJECT_PT_rls_lidar_preview,
    OBJECT_PT_rls_lidar_metrics,
    OBJECT_PT_rls_infralob,
    OBJECT_PT_rls_label,
    SCENE_PT_rls_evaluate,
)

__all__ = ["CLASSES", "family_menus", "sync_family_menus", "unregister_family_menus",
           "draw_add_menu", "VIEW3D_MT_rls_add", "RLS_PT_device_presets",
           "OBJECT_PT_rls_lidar", "OBJECT_PT_rls_lidar_range", "OBJECT_PT_rls_lidar_motion",
           "OBJECT_PT_rls_lidar_output", "OBJECT_PT_rls_lidar_preview",
           "OBJECT_PT_rls_lidar_metrics", "OBJECT_PT_rls_infralob", "OBJECT_PT_rls_label",
           "SCENE_PT_rls_evaluate"]
