"""Blender properties, a module per owner: ``Object.rls_lidar`` (lidar.py),
``Scene.rls`` (scene.py, with Detect and Evaluate's in evaluation.py), ``Scene.rls_study``
(study.py) and ``Scene.rls_live`` (live.py).

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
from .live import RLS_LiveSettings
from .study import RLS_StudyRow, RLS_StudySettings

__all__ = ["CLASSES", "COLOR_ITEMS", "RLS_LidarSettings", "RLS_SceneSettings", "RLS_StudyRow",
           "RLS_StudySettings", "RLS_LiveSettings", "lidar_mode_items",
           "preset_items", "refresh_preset_items", "register_properties", "unregister_properties"]

CLASSES = (RLS_LidarSettings, RLS_APRow, RLS_EvaluationSettings, RLS_SceneSettings,
           RLS_StudyRow, RLS_StudySettings, RLS_LiveSettings)


def register_properties():
    bpy.types.Object.rls_lidar = PointerProperty(type=RLS_LidarSettings)
    bpy.types.Scene.rls = PointerProperty(type=RLS_SceneSettings)
    bpy.types.Scene.rls_study = PointerProperty(type=RLS_StudySettings)
    bpy.types.Scene.rls_live = PointerProperty(type=RLS_LiveSettings)


def unregister_properties():
    del bpy.types.Scene.rls_live
    del bpy.types.Scene.rls_study
    del bpy.types.Scene.rls
    del bpy.types.Object.rls_lidar
    _ITEMS["presets"] = []
    _ITEMS["old"].clear()
    preset_catalog.clear()
