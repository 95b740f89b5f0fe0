"""Motion of what collection instances place, read through the Blender layer.

A depsgraph instance names only its top instancer and its object. Before the fix, an
instance was sampled over the sweep only when that object or that instancer was
animated and in the scene: a keyed object in a collection not linked to the scene, or
a keyed empty between two instancers (a nested collection instance), was read as
still, its points frozen where the sweep began (2.4 m off at 24 m/s by the sweep's
end), without a word."""

import bpy
import numpy as np
import pytest

from .conftest import add_lidar, mesh_object, scan
from .test_motion_ghosts import linear_keys

FPS = 24  # the factory scene's frame rate; keys 1 m apart per frame: 24 m/s


def wall(name, collection):
    return mesh_object(name, [(0, -3, 0), (0, 3, 0), (0, 3, 4), (0, -3, 4)], [(0, 1, 2, 3)],
                       collection=collection)


def instancer(name, coll, collection):
    obj = bpy.data.objects.new(name, None)
    obj.instance_type = "COLLECTION"
    obj.instance_collection = coll
    collection.objects.link(obj)
    return obj


def wall_points(scene):
    lidar = add_lidar(location=(0, 0, 2))
    lidar.rls_lidar.frame_space = "world"
    scene.frame_set(6)
    p = scan(lidar, 6)[0].points
    on = p["x"] > 1
    assert on.sum() > 1000
    return p["x"][on], p["time"][on]


@pytest.mark.parametrize("linked", [False, True])
def test_keyed_object_in_an_instanced_collection_moves(scene, linked):
    coll = bpy.data.collections.new("Proto")
    if linked:  # in the scene but excluded from the view layer (or not in it at all)
        scene.collection.children.link(coll)
        bpy.context.view_layer.layer_collection.children["Proto"].exclude = True
    mover = wall("Mover", coll)
    linear_keys(mover, "location", [(1, (5.0, 0.0, 0.0)), (11, (15.0, 0.0, 0.0))])
    instancer("Instancer", coll, scene.collection)
    x, t = wall_points(scene)
    assert np.abs(x - (10.0 + FPS * t)).max() < 1e-4
    assert x.max() > 12.0  # it moved 2.4 m over the sweep


def test_keyed_empty_inside_a_nested_collection_instance_moves(scene):
    leaf, outer = bpy.data.collections.new("Leaf"), bpy.data.collections.new("Outer")
    for c in (leaf, outer):
        scene.collection.children.link(c)
        bpy.context.view_layer.layer_collection.children[c.name].exclude = True
    wall("Wall", leaf)
    inner = instancer("Inner", leaf, outer)
    linear_keys(inner, "location", [(1, (5.0, 0.0, 0.0)), (11, (15.0, 0.0, 0.0))])
    instancer("Top", outer, scene.collection)
    x, t = wall_points(scene)
    assert np.abs(x - (10.0 + FPS * t)).max() < 1e-4
    assert x.max() > 12.0
