"""InfraLOB region objects: outline of a flat mesh in world xy."""

import math

import numpy as np
import pytest

from rls_addon.blender.region import is_lob, lob_polygon_world
from rls_addon.core.errors import RegionError
from rls_addon.core.metrics.polygon import polygon_area

from .conftest import bpy, mesh_object


def test_single_ngon_outline_in_world_xy(scene):
    obj = mesh_object("Lob", [(0, 0, 0), (4, 0, 0), (4, 2, 0), (2, 2, 0), (2, 4, 0), (0, 4, 0)], [(0, 1, 2, 3, 4, 5)])
    obj.location = (10, 20, 5)
    obj.rotation_euler = (0, 0, math.pi / 2)
    bpy.context.view_layer.update()
    poly = lob_polygon_world(obj)
    np.testing.assert_allclose(poly[1], [10, 24], atol=1e-9)
    assert polygon_area(poly) == pytest.approx(12.0)
    assert not is_lob(obj)
    obj["rls_infralob"] = True
    assert is_lob(obj)


def test_subdivided_grid_boundary_is_chained(scene):
    verts = [(x, y, 0) for y in range(3) for x in range(4)]
    faces = [(y * 4 + x, y * 4 + x + 1, (y + 1) * 4 + x + 1, (y + 1) * 4 + x) for y in range(2) for x in range(3)]
    poly = lob_polygon_world(mesh_object("Grid", verts, faces))
    assert len(poly) == 10
    assert polygon_area(poly) == pytest.approx(6.0)


def test_non_mesh_and_faceless_are_region_errors(scene):
    empty = bpy.data.objects.new("E", None)
    with pytest.raises(RegionError, match="not a mesh"):
        lob_polygon_world(empty)
    with pytest.raises(RegionError, match="no faces"):
        lob_polygon_world(mesh_object("Line", [(0, 0, 0), (1, 0, 0)], []))


def test_metrics_command_reads_region_from_blend(scene, tmp_path):
    import json

    from rls_addon.core.output.io import write_cloud
    from rls_addon.core.points import empty_points

    from ..cli.conftest import rls

    obj = mesh_object("Lob", [(0, 0, 0), (20, 0, 0), (20, 30, 0), (0, 30, 0)], [(0, 1, 2, 3)])
    obj["rls_infralob"] = True
    blend = tmp_path / "lob.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    gx, gy = np.meshgrid(np.arange(0.25, 20, 0.5), np.arange(0.25, 30, 0.5))
    pts = empty_points(gx.size)
    pts["x"], pts["y"], pts["label"] = gx.ravel(), gy.ravel(), 2
    cloud = write_cloud(tmp_path / "c.pcd", pts)
    proc = rls("metrics", "--lob", f"{blend}:Lob", "--disks", 100, cloud)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["infra_d"] == 4.0 and out["area_m2"] == pytest.approx(600.0)


def test_a_region_whose_modifiers_change_its_outline_is_refused(scene):
    """An audit found a 10 x 10 m plane with a Mirror modifier (20 x 10 m in the
    viewport) read as its mesh alone: half the region ignored and InfraD doubled, with
    no word. The outline is the mesh's own, so shown modifiers are refused with what to
    do; one hidden in the viewport shows the mesh that is read, and is left alone."""
    plane = mesh_object("LOB", [(0, 0, 0), (10, 0, 0), (10, 10, 0), (0, 10, 0)], [(0, 1, 2, 3)])
    mirror = plane.modifiers.new("Mirror", "MIRROR")
    with pytest.raises(RegionError, match=r"'LOB' has modifiers \(Mirror\).*Apply"):
        lob_polygon_world(plane)
    mirror.show_viewport = False
    assert polygon_area(lob_polygon_world(plane)) == pytest.approx(100.0)
