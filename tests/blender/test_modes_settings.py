"""A LiDAR's rotation rate and lidar mode (issue #32): the panel's properties become
settings, the scan's preset runs in them, the sidecar records them."""

import json

import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground, user_dir  # noqa: F401 (fixture)


def test_lidar_mode_enum_lists_the_presets_modes(scene, user_dir):
    from rls_addon.blender.sensor import read_settings, sensor_job
    from rls_addon.properties import lidar_mode_items

    obj = add_lidar_op("ouster_os1_64")
    s = obj.rls_lidar
    ids = [it[0] for it in lidar_mode_items(s, bpy.context)]
    assert ids == ["DEFAULT", "512x10", "512x20", "1024x10", "1024x20", "2048x10"]
    assert read_settings(obj).scan.lidar_mode is None
    assert len(sensor_job(obj).preset.pattern()) == 1024 * 64
    s.lidar_mode = "2048x10"
    assert read_settings(obj).scan.lidar_mode == "2048x10"
    assert len(sensor_job(obj).preset.pattern()) == 2048 * 64
    other = add_lidar_op("velodyne_vlp16")
    assert [it[0] for it in lidar_mode_items(other.rls_lidar, bpy.context)] == ["DEFAULT"]


def test_rotation_hz_property_reaches_the_scan_and_sidecar(scene, user_dir, tmp_path):
    from rls_addon.blender.sensor import read_settings, sensor_job
    from rls_addon.core.errors import SettingsError

    labelled_ground()
    obj = add_lidar_op("hesai_pandarxt32", out=tmp_path)
    s = obj.rls_lidar
    assert read_settings(obj).scan.rotation_hz is None
    s.use_rotation_hz = True
    s.rotation_hz = 10.017
    job = sensor_job(obj)
    assert job.preset.frequency_hz == pytest.approx(10.017)
    assert len(job.preset.pattern()) == 2000 * 32  # motor-locked
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    sides = list(tmp_path.rglob("*_LiDAR_*.json"))
    assert len(sides) == 1
    info = json.loads(sides[0].read_text())
    assert info["effects"]["rotation_hz"] == pytest.approx(10.017)
    s.rotation_hz = 15.0
    with pytest.raises(SettingsError, match="10, 20 Hz"):
        sensor_job(obj)
