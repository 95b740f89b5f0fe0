"""Blender properties, a module per owner: ``Object.rls_lidar`` (lidar.py) and
``Scene.rls`` (scene.py, with Detect and Evaluate's in evaluation.py).

Only plain values live here; ``blender.sensor.read_settings`` maps them into the core's
``LidarSettings`` in one place. Enumerations come from ``core.choices``, the same lists
the core validates with and the command line offers.
"""

import bpy
from bpy.props import PointerProperty

from ..blender import preset_catalog
from .lidar import (_ITEMS, COLOR_ITEMS, RLS_LidarSettings, lidar_mode_items, preset_items,
                    refresh_preset_items)
from .evaluation import RLS_APRow, RLS_EvaluationSettings
from .scene import RLS_SceneSettings

__all__ = ["CLASSES", "COLOR_ITEMS", "RLS_LidarSettings", "RLS_SceneSettings", "lidar_mode_items",
           "preset_items", "refresh_preset_items", "register_properties", "unregister_properties"]

CLASSES = (RLS_LidarSettings, RLS_APRow, RLS_EvaluationSettings, RLS_SceneSettings)


def register_properties():
    bpy.types.Object.rls_lidar = PointerProperty(type=RLS_LidarSettings)
    bpy.types.Scene.rls = PointerProperty(type=RLS_SceneSettings)


def unregister_properties():
    del bpy.types.Scene.rls
    del bpy.types.Object.rls_lidar
    _ITEMS["presets"] = []
    _ITEMS["old"].clear()
    preset_catalog.clear()
