"""Geometry nodes that make instances of geometry they generate (an audit found them
scanned wrong without a word: the object's own mesh dropped, a 1 m cube read as the
2 m one beside it, both under one instance id; with exact motion a bare KeyError).
They are refused with what to do; the same tree with a Realize Instances node is
scanned as a render shows it."""

import numpy as np
import pytest

from rls_addon.blender.extract import read_instances
from rls_addon.core.errors import SceneError

from .conftest import add_lidar, bpy, mesh_object, scan


def _wall_with_cubes(realize):
    """A wall at x = 10 whose node tree joins its own mesh with a 1 m cube at y = -3
    and a 2 m cube at y = 3 (both centred at x = 6, z = 1), instanced on points;
    ``realize``: a Realize Instances node before the output."""
    wall = mesh_object("Base", [(10, -8, 0), (10, 8, 0), (10, 8, 4), (10, -8, 4)],
                       [(0, 1, 2, 3)])
    tree = bpy.data.node_groups.new("Cubes", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    given, out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    join = nodes.new("GeometryNodeJoinGeometry")
    for y, size in ((-3.0, 1.0), (3.0, 2.0)):
        point = nodes.new("GeometryNodePoints")
        point.inputs["Count"].default_value = 1
        point.inputs["Position"].default_value = (6.0, y, 1.0)
        cube = nodes.new("GeometryNodeMeshCube")
        cube.inputs["Size"].default_value = (size, size, size)
        on = nodes.new("GeometryNodeInstanceOnPoints")
        links.new(point.outputs["Points"], on.inputs["Points"])
        links.new(cube.outputs["Mesh"], on.inputs["Instance"])
        links.new(on.outputs["Instances"], join.inputs["Geometry"])
    links.new(given.outputs["Geometry"], join.inputs["Geometry"])
    last = join.outputs["Geometry"]
    if realize:
        real = nodes.new("GeometryNodeRealizeInstances")
        links.new(last, real.inputs["Geometry"])
        last = real.outputs["Geometry"]
    links.new(last, out.inputs["Geometry"])
    wall.modifiers.new("Cubes", "NODES").node_group = tree
    return wall


@pytest.mark.parametrize("motion", ["exact", "snapshot"])
def test_instances_of_generated_geometry_are_refused_with_the_fix(scene, motion):
    _wall_with_cubes(realize=False)
    lidar = add_lidar(location=(0, 0, 1))
    lidar.rls_lidar.motion = motion
    with pytest.raises(SceneError, match="'Base'.*Realize Instances"):
        scan(lidar)
    with pytest.raises(SceneError, match="Realize Instances"):
        read_instances(bpy.context.evaluated_depsgraph_get())


def test_realized_instances_are_scanned_where_a_render_shows_them(scene):
    _wall_with_cubes(realize=True)
    lidar = add_lidar(location=(0, 0, 1))
    s = lidar.rls_lidar
    s.noise, s.dropout, s.frame_space = False, False, "world"
    result, _ = scan(lidar)
    p = result.points
    x, y = p["x"], p["y"]
    wall = np.isclose(x, 10.0, atol=1e-3)
    small = np.isclose(x, 5.5, atol=1e-3)   # the 1 m cube's front face
    big = np.isclose(x, 5.0, atol=1e-3)     # the 2 m cube's front face
    assert wall.any() and small.any() and big.any()
    assert np.all(np.abs(y[small] + 3.0) <= 0.5 + 1e-3)
    assert np.all(np.abs(y[big] - 3.0) <= 1.0 + 1e-3)


def test_objects_left_out_of_the_read_are_not_refused(scene):
    """The refusal is for what would be scanned: not an object hidden from render, nor
    RLS's own drawings (a preview's points are instanced by geometry nodes too)."""
    wall = _wall_with_cubes(realize=False)
    wall.hide_render = True
    lidar = add_lidar(location=(0, 0, 1))
    read_instances(bpy.context.evaluated_depsgraph_get(), exclude={lidar.name})
    wall.hide_render = False
    wall["rls_preview"] = True
    read_instances(bpy.context.evaluated_depsgraph_get(), exclude={lidar.name})
