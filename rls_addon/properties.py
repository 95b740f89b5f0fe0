"""Blender properties: one ``PropertyGroup`` per LiDAR object."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from .core.presets import builtin_presets

_PRESET_ITEMS = []

FORMAT_ITEMS = [
    ("pcd_binary", "PCD binary", "PCD v0.7, binary"),
    ("pcd_binary_compressed", "PCD binary compressed", "PCD v0.7, LZF-compressed binary"),
    ("pcd_ascii", "PCD ASCII", "PCD v0.7, text"),
    ("ply_binary", "PLY binary", "PLY, binary little endian"),
    ("ply_ascii", "PLY ASCII", "PLY, text"),
]


def preset_items(self, context):
    """Enum items of the device presets (kept referenced, as Blender requires)."""
    if not _PRESET_ITEMS:
        for i, p in enumerate(builtin_presets().values()):
            _PRESET_ITEMS.append((p.id, p.name, f"{p.family}: {p.source}", i))
    return _PRESET_ITEMS


class RLS_LidarSettings(bpy.types.PropertyGroup):
    is_lidar: BoolProperty(name="Is LiDAR", default=False,
                           description="This object is a LiDAR sensor; its axes are the sensor frame")
    preset: EnumProperty(name="Device", items=preset_items,
                         description="Device preset: scan pattern, range and noise of a real sensor")
    seed: IntProperty(name="Seed", default=0, min=0,
                      description="Seed of the scan's random generator (noise, dropout)")
    noise: BoolProperty(name="Range Noise", default=True)
    dropout: BoolProperty(name="Dropout", default=True)
    use_max_range: BoolProperty(name="Override Range", default=False)
    max_range: FloatProperty(name="Max Range", default=100.0, min=0.1, soft_max=500.0,
                             unit="LENGTH")
    frame_space: EnumProperty(name="Frame", default="SENSOR", items=[
        ("SENSOR", "Sensor", "Point coordinates in the sensor frame"),
        ("WORLD", "World", "Point coordinates in world space")])
    output_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//lidar/")
    file_format: EnumProperty(name="Format", items=FORMAT_ITEMS, default="pcd_binary")
    name_template: StringProperty(name="Names", default="{scene}_{sensor}_{frame:06d}")


CLASSES = (RLS_LidarSettings,)


def register_properties():
    bpy.types.Object.rls_lidar = bpy.props.PointerProperty(type=RLS_LidarSettings)


def unregister_properties():
    del bpy.types.Object.rls_lidar
    _PRESET_ITEMS.clear()
