"""Issue 41 in Blender: the toy device family and output format of
tests/toy_extensions.py, added through the registries alone while the extension is
enabled, appear in the Add > LiDAR menus (a menu of their own), the preset list, the
LiDAR panel's family label and the Format list; a LiDAR with the toy device scans with
Scan Frame into the toy format. Taken out, their menu and items go with them."""

from types import SimpleNamespace

import numpy as np

from tests import toy_extensions as toy

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground, user_dir  # noqa: F401 (fixture)
from .test_ui_panels import _draw

MENU = f"VIEW3D_MT_rls_add_{toy.FAMILY_ID}"


def _ids(items):
    return [it[0] for it in items if it]


def test_a_toy_family_and_format_show_in_the_ui_and_scan(scene, user_dir, tmp_path):
    from rls_addon import ui
    from rls_addon.core.output.io import read_cloud, read_sidecar
    from rls_addon.properties.lidar import format_items, preset_items

    toy.write_preset(user_dir)
    assert not hasattr(bpy.types, MENU) and "toy_fan_64" not in _ids(preset_items(None, None))
    with toy.registered():
        assert hasattr(bpy.types, MENU) and MENU in [m.bl_idname for m in ui.family_menus()]
        items = preset_items(None, None)
        assert "Toy Fan" in [it[1] for it in items if it and not it[0]]  # the family heading
        assert "toy_fan_64" in _ids(items)
        assert toy.FORMAT_ID in _ids(format_items(None, None))

        labelled_ground()
        obj = add_lidar_op("toy_fan_64", out=tmp_path, show_fov=False,
                           file_format=toy.FORMAT_ID)
        assert obj.rls_lidar.file_format == toy.FORMAT_ID
        ctx = SimpleNamespace(object=obj, active_object=obj, scene=scene)
        top = _draw(ui.VIEW3D_MT_rls_add, ctx)
        assert (MENU,) in [a for n, a, _ in top if n == "menu"]
        assert {"icon": "LIGHT_AREA"} in [kw for n, a, kw in top if a == (MENU,)]
        listed = [kw.get("text") for n, _, kw in _draw(getattr(bpy.types, MENU), ctx)
                  if n == "operator"]
        assert listed == ["Toy Fan 64"]
        labels = [kw.get("text", "") for n, _, kw in _draw(ui.OBJECT_PT_rls_lidar, ctx)
                  if n == "label"]
        assert "Toy Fan, user preset" in labels

        assert bpy.ops.rls.scan_frame() == {"FINISHED"}
        path = tmp_path / "Scene_LiDAR_000001.toy"
        points = read_cloud(path)
        assert read_sidecar(path)["format"] == toy.FORMAT_ID and len(points) == 64
        # the fan at -30 degrees from 2 m over the ground meets it at 4 m
        rng = np.sqrt(points["x"].astype(float) ** 2 + points["y"] ** 2 + points["z"] ** 2)
        assert np.abs(rng - 4.0).max() < 1e-4
    assert not hasattr(bpy.types, MENU)
    assert MENU not in [m.bl_idname for m in ui.family_menus()]
    assert "toy_fan_64" not in _ids(preset_items(None, None))
    assert toy.FORMAT_ID not in _ids(format_items(None, None))
    ctx = SimpleNamespace(object=None, active_object=None, scene=scene)
    assert (MENU,) not in [a for n, a, _ in _draw(ui.VIEW3D_MT_rls_add, ctx) if n == "menu"]
