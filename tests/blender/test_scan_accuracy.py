"""Scans of analytic scenes through the Blender layer (extraction + BVHTree)."""

import numpy as np
import pytest

from .conftest import add_lidar, ground, mesh_object, scan, xyz


@pytest.mark.parametrize("origin", [(0.0, 0.0, 0.0), (1.0e5, -1.0e5, 40.0)])
def test_plane_at_known_distance_ranges_exact(scene, origin):
    """Plane 3 m below the sensor: every downward ray has range 3 / sin(-elevation)."""
    ox, oy, oz = origin
    mesh_object("Ground", [(ox - 80, oy - 80, oz), (ox + 80, oy - 80, oz),
                           (ox + 80, oy + 80, oz), (ox - 80, oy + 80, oz)], [(0, 1, 2, 3)])
    lidar = add_lidar(location=(ox, oy, oz + 3.0))
    result, info = scan(lidar)
    p = result.points
    assert len(p) > 1000
    d = xyz(p) / p["range"][:, None]
    expected = 3.0 / -d[:, 2]
    assert np.max(np.abs(p["range"] - expected)) <= 1e-4
    assert np.max(np.abs(p["z"] + 3.0)) <= 1e-4
    # Every ray with elevation below the horizon that reaches the plane within range hits it.
    assert info["points"] == len(p) and info["rays"] == result.rays


def test_hidden_from_render_and_far_objects_are_skipped(scene):
    ground()
    wall = mesh_object("Wall", [(5, -5, 0), (5, 5, 0), (5, 5, 5), (5, -5, 5)], [(0, 1, 2, 3)])
    far = mesh_object("Far", [(500, -5, 0), (500, 5, 0), (500, 5, 5), (500, -5, 5)],
                      [(0, 1, 2, 3)])
    lidar = add_lidar(location=(0, 0, 2))
    result, info = scan(lidar)
    assert info["objects_culled_by_range"] == 1  # 'Far' is beyond the 100 m range
    with_wall = np.sum(np.isclose(result.points["x"], 5.0, atol=1e-4))
    assert with_wall > 0
    wall.hide_render = True
    result2, _ = scan(lidar)
    assert np.sum(np.isclose(result2.points["x"], 5.0, atol=1e-4)) == 0
    assert far.name == "Far"


def test_modifiers_and_collection_instances_are_scanned(scene):
    import bpy

    ground()
    # An array modifier turns one post into three.
    post = mesh_object("Post", [(4, -0.5, 0), (4, 0.5, 0), (4, 0.5, 4), (4, -0.5, 4)],
                       [(0, 1, 2, 3)])
    mod = post.modifiers.new("Array", "ARRAY")
    mod.count = 3
    mod.use_relative_offset = False
    mod.use_constant_offset = True
    mod.constant_offset_displace = (0.0, 3.0, 0.0)
    # A collection instance of a wall, placed behind the sensor.
    coll = bpy.data.collections.new("Prototype")
    mesh_object("Proto wall", [(0, -2, 0), (0, 2, 0), (0, 2, 4), (0, -2, 4)], [(0, 1, 2, 3)],
                collection=coll)
    inst = bpy.data.objects.new("Instance", None)
    inst.instance_type = "COLLECTION"
    inst.instance_collection = coll
    inst.location = (-6.0, 0.0, 0.0)
    scene.collection.objects.link(inst)
    lidar = add_lidar(location=(0, 0, 1.5))
    p = scan(lidar)[0].points
    at_post = np.isclose(p["x"], 4.0, atol=1e-4)
    ys = p["y"][at_post]
    assert (np.abs(ys - 0) < 0.5).any() and (np.abs(ys - 3) < 0.5).any() and (np.abs(ys - 6) < 0.5).any()
    assert np.isclose(p["x"], -6.0, atol=1e-4).sum() > 0


def test_labels_from_collection_and_property(scene):
    import bpy

    roads = bpy.data.collections.new("Road")
    scene.collection.children.link(roads)
    g = ground()
    scene.collection.objects.unlink(g)
    roads.objects.link(g)
    wall = mesh_object("Wall", [(5, -5, 0), (5, 5, 0), (5, 5, 5), (5, -5, 5)], [(0, 1, 2, 3)])
    wall["rls_label"] = "building"
    lidar = add_lidar(location=(0, 0, 2))
    result, info = scan(lidar)
    p = result.points
    on_wall = np.isclose(p["x"], 5.0, atol=1e-4)
    assert set(np.unique(p["label"][on_wall])) == {3}
    assert set(np.unique(p["label"][np.isclose(p["z"], -2.0, atol=1e-4)])) == {1}
    names = {v["object"]: v["label"] for v in info["labels"].values()}
    assert names == {"Ground": 1, "Wall": 3}


def test_empty_scene_gives_no_points_and_a_warning(scene):
    lidar = add_lidar()
    result, info = scan(lidar)
    assert len(result.points) == 0
    assert any("no geometry" in w for w in info["warnings"])


def test_static_geometry_is_built_once_and_rebuilt_when_it_changes(scene):
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.casting import BVHCaster
    from rls_addon.core.scan.session import ScanSession

    ground()
    box = mesh_object("Box", [(5, -1, 0), (5, 1, 0), (5, 1, 3), (5, -1, 3)], [(0, 1, 2, 3)])
    lidar = add_lidar(location=(0, 0, 2))
    session, source = ScanSession(BVHCaster), BlenderScene(scene)
    outs = []
    for frame in (1, 2, 3):
        outs.append(scan_lidar(lidar, frame, session=session, source=source)[0])
    assert session.builds == 1
    assert outs[0].points.tobytes() == outs[2].points.tobytes()
    box.location.x += 1.0
    p = scan_lidar(lidar, 4, session=session, source=source)[0].points
    assert session.builds == 2
    assert np.isclose(p["x"], 6.0, atol=1e-4).sum() > 0
