"""Shared helpers for the operator and UI tests (background mode, no window)."""

import pytest

from .conftest import bpy


@pytest.fixture
def user_dir(tmp_path, addon):
    """A private user preset folder for one test."""
    from rls_addon.blender import preset_catalog
    from rls_addon import properties

    d = tmp_path / "user_presets"
    preset_catalog.set_user_dir(d)
    properties.refresh_preset_items()
    yield d
    preset_catalog.set_user_dir(None)
    properties.refresh_preset_items()


def add_lidar_op(preset="generic_uniform32", location=(0.0, 0.0, 2.0), out=None, **settings):
    """Add a LiDAR through the operator, as a user would; returns it (active, selected)."""
    bpy.context.scene.cursor.location = location
    assert bpy.ops.object.rls_add_lidar(preset=preset) == {"FINISHED"}
    obj = bpy.context.active_object
    s = obj.rls_lidar
    s.noise = False
    s.dropout = False
    if out is not None:
        s.output_dir = str(out)
    for k, v in settings.items():
        setattr(s, k, v)
    return obj


def labelled_ground(size=40.0, label="road"):
    from .conftest import ground

    g = ground(size)
    g["rls_label"] = label
    return g
