"""InfraLOB and preview operators in background mode: add a region, compute InfraD /
InfraNUC from the preview points of every LiDAR, the density map image, colouring."""

import numpy as np
import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground


def _scan_two_lidars():
    labelled_ground(40.0)
    add_lidar_op(location=(-5.0, 0.0, 3.0))
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    add_lidar_op(location=(5.0, 0.0, 3.0))
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}


def test_add_infralob(scene):
    scene.cursor.location = (1.0, 2.0, 0.0)
    assert bpy.ops.object.rls_add_infralob(size_x=10.0, size_y=6.0) == {"FINISHED"}
    lob = bpy.context.active_object
    assert lob["rls_infralob"] is True and lob.hide_render and lob.display_type == "WIRE"
    assert scene.rls.lob == lob
    from rls_addon.blender.region import lob_polygon_world
    from rls_addon.core.metrics.polygon import polygon_area

    poly = lob_polygon_world(lob)
    assert polygon_area(poly) == pytest.approx(60.0)
    assert poly.min(0) == pytest.approx([-4.0, -1.0]) and poly.max(0) == pytest.approx([6.0, 5.0])


def test_metrics_from_preview_points_of_all_lidars(scene):
    from rls_addon.blender.preview import preview_world_points
    from rls_addon.core.metrics.infra import infra_lob_metrics
    from rls_addon.core.points import empty_points

    _scan_two_lidars()
    scene.cursor.location = (0.0, 0.0, 0.0)
    assert bpy.ops.object.rls_add_infralob(size_x=20.0, size_y=20.0) == {"FINISHED"}
    rs = scene.rls
    rs.metric_disks = 500
    assert bpy.ops.rls.compute_metrics() == {"FINISHED"}
    assert rs.has_metrics and rs.metric_lob_name == "InfraLOB"
    assert rs.metric_sensors == "LiDAR, LiDAR.001"
    # the same numbers as the core on the same world-frame points
    clouds = []
    for name in ("LiDAR points", "LiDAR.001 points"):
        co, lab = preview_world_points(bpy.data.objects[name])
        p = empty_points(len(co))
        p["x"], p["y"], p["label"] = co[:, 0], co[:, 1], lab
        clouds.append(p)
    ref = infra_lob_metrics(clouds, [(-10, -10), (10, -10), (10, 10), (-10, 10)], disks=500)
    assert rs.infra_d == pytest.approx(ref.infra_d, rel=1e-6)
    assert rs.infra_nuc == pytest.approx(ref.infra_nuc, rel=1e-5)
    assert rs.metric_points == ref.n_points and rs.metric_area == pytest.approx(400.0)
    img = rs.metric_image
    # the command line's chart (a 7.5 in figure at 100 dpi), not the bare 20 x 20 cells
    assert img is not None and img.size[0] == 750 and img.packed_file is not None
    px = np.empty(img.size[0] * img.size[1] * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, 3].max() == 1.0 and px.reshape(-1, 4)[:, :3].max() > 0.5
    title = img["rls_title"]
    assert "LiDAR + LiDAR.001, region InfraLOB in Scene" in title  # not saved: no file
    assert f"InfraD {ref.infra_d:.2f} points / m²" in title
    # recomputing replaces the image instead of piling up copies
    assert bpy.ops.rls.compute_metrics() == {"FINISHED"}
    assert len([i for i in bpy.data.images if i.name.startswith("RLS density")]) == 1


def test_metrics_chart_names_the_scene_file(scene, tmp_path):
    pytest.importorskip("matplotlib")
    _scan_two_lidars()
    bpy.ops.object.rls_add_infralob(size_x=20.0, size_y=20.0)
    scene.rls.metric_disks = 100
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "crossing.blend"))
    assert bpy.ops.rls.compute_metrics() == {"FINISHED"}
    title = scene.rls.metric_image["rls_title"]
    assert "region InfraLOB in crossing.blend" in title and "Scene" not in title


def test_metrics_bad_input(scene):
    with pytest.raises(RuntimeError, match="Select an InfraLOB region"):
        bpy.ops.rls.compute_metrics()
    bpy.ops.object.rls_add_infralob()
    add_lidar_op()
    bpy.context.view_layer.objects.active = bpy.data.objects["InfraLOB"]
    with pytest.raises(RuntimeError, match="No LiDAR points to measure: scan a frame first"):
        bpy.ops.rls.compute_metrics()
    # points, but none labelled road or sidewalk in the region
    labelled_ground(label="building")
    bpy.context.view_layer.objects.active = bpy.data.objects["LiDAR"]
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="InfraLOB: .*holds no points labelled road, sidewalk"):
        bpy.ops.rls.compute_metrics()
    scene.rls.metric_labels = "starship"
    with pytest.raises(RuntimeError, match="unknown label 'starship'"):
        bpy.ops.rls.compute_metrics()
    assert not scene.rls.has_metrics


@pytest.mark.parametrize("attribute", ["intensity", "label", "time", "ring"])
def test_preview_colour_by_attribute(scene, attribute):
    labelled_ground()
    obj = add_lidar_op()
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    assert bpy.ops.rls.preview_color(attribute=attribute) == {"FINISHED"}
    assert obj.rls_lidar.preview_color == attribute
    prev = bpy.data.objects["LiDAR points"]
    mat = prev.modifiers["RLS Points"][_socket(prev, "Material")]
    assert mat.name == "LiDAR points colors" and prev.data.materials[0] == mat
    nodes = mat.node_tree.nodes
    attr = [n for n in nodes if n.bl_idname == "ShaderNodeAttribute"]
    assert len(attr) == 1 and attr[0].attribute_name == attribute
    assert attr[0].attribute_type == "GEOMETRY"
    ramp = next(n for n in nodes if n.bl_idname == "ShaderNodeValToRGB")
    assert ramp.color_ramp.interpolation == ("CONSTANT" if attribute == "label" else "LINEAR")
    remap = next(n for n in nodes if n.bl_idname == "ShaderNodeMapRange")
    assert remap.inputs["From Max"].default_value > 0
    # the next scan keeps the chosen colouring
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    assert prev["rls_color_by"] == attribute
    # the evaluated preview is a point cloud carrying the attribute
    ev = prev.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert any(i.object.type == "POINTCLOUD" and i.object.name == prev.name
               for i in bpy.context.evaluated_depsgraph_get().object_instances)
    assert ev is not None


def test_preview_colour_needs_points(scene):
    with pytest.raises(RuntimeError, match="Select a LiDAR or its preview points"):
        bpy.ops.rls.preview_color(attribute="label")
    add_lidar_op()
    with pytest.raises(RuntimeError, match="No preview points to colour: scan a frame first"):
        bpy.ops.rls.preview_color(attribute="label")


def _socket(obj, name):
    ng = obj.modifiers["RLS Points"].node_group
    return next(i.identifier for i in ng.interface.items_tree
                if getattr(i, "in_out", None) == "INPUT" and i.name == name)
