"""*File > Import*: SUMO Network as Scene and Generated SUMO Traffic beside SUMO Traffic;
bad input is one error and leaves the file as it was. That they build and write what
the command line does: tests/cli/test_ui_matches_cli.py."""

from types import SimpleNamespace

import pytest

from .conftest import bpy


def test_import_menu_lists_network_and_generated_traffic(addon):
    from rls_addon.operators import roads, traffic

    log = []
    menu = SimpleNamespace(layout=SimpleNamespace(operator=lambda idname, **kw: log.append(idname)))
    roads.draw_import_menu(menu, bpy.context)
    traffic.draw_import_menu(menu, bpy.context)
    assert log == ["rls.import_sumo_network", "rls.import_sumo_traffic",
                   "rls.generate_sumo_traffic"]


def test_bad_network_is_one_error_and_adds_nothing(scene, tmp_path):
    scenes = len(bpy.data.scenes)
    with pytest.raises(RuntimeError, match="not found"):
        bpy.ops.rls.import_sumo_network(filepath=str(tmp_path / "missing.net.xml"))
    broken = tmp_path / "broken.net.xml"
    broken.write_text("<net><edge id='a'")
    with pytest.raises(RuntimeError, match="broken.net.xml"):
        bpy.ops.rls.import_sumo_network(filepath=str(broken))
    with pytest.raises(RuntimeError, match="Choose a SUMO network"):
        bpy.ops.rls.import_sumo_network()
    assert len(bpy.data.scenes) == scenes and bpy.context.scene == scene
    objects = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match="not found"):
        bpy.ops.rls.generate_sumo_traffic(filepath=str(tmp_path / "missing.net.xml"))
    assert len(bpy.data.objects) == objects and not list(tmp_path.glob("*.fcd.xml"))


def test_generated_traffic_goes_beside_the_network_by_default():
    from rls_addon.operators.traffic import fcd_path_for

    assert fcd_path_for("/d/crossing.net.xml") == "/d/crossing.fcd.xml"
    assert fcd_path_for("/d/town.xml") == "/d/town.fcd.xml"
