"""What a render shows of instancers, read from the viewport's depsgraph.

The viewport shows an instancer's own mesh with *Instancing > Viewport* on, a render
only with *Instancing > Render* on (``show_instancer_for_render``; *Show Emitter* of a
particle system); and a render never shows a child of an object instancing on its
vertices or faces at the child's own place, only at those vertices or faces. Before the
fix RLS scanned both (the spawner's face and the prototype where it stood) without a
word, points on surfaces a render of the scene does not have."""

import bpy
import numpy as np

from .conftest import add_lidar, ground, mesh_object, scan


def instance_names(lidar):
    result, info = scan(lidar)
    p = result.points
    by_id = {int(k): v["object"] for k, v in info["labels"].items()}
    return p, [by_id[int(i)] for i in p["instance"]]


def test_vertex_instancer_hidden_in_render_and_its_prototype_are_not_scanned(scene):
    spawner = mesh_object("Spawner", [(8, -4, 0), (8, 4, 0), (8, 4, 4), (8, -4, 4)],
                          [(0, 1, 2, 3)])
    post = mesh_object("Post", [(0, -0.3, 0), (0, 0.3, 0), (0, 0.3, 2), (0, -0.3, 2)],
                       [(0, 1, 2, 3)])
    post.parent = spawner
    post.location = (-4, 0, 0)  # its own place: x = -4, in range of the sensor
    spawner.instance_type = "VERTS"
    spawner.show_instancer_for_render = False
    lidar = add_lidar(location=(2, 0, 2))
    lidar.rls_lidar.frame_space = "world"
    p, names = instance_names(lidar)
    # only the posts at the spawner's two lower vertices (x = 4, y = +-4)
    assert len(p) > 100
    assert all(n.startswith("Spawner/Post#") for n in names)
    assert np.allclose(p["x"], 4.0, atol=1e-4)
    assert np.all(np.abs(np.abs(p["y"]) - 4.0) <= 0.3 + 1e-4)
    # with Instancing > Render on, a render shows the spawner's face too
    spawner.show_instancer_for_render = True
    p, names = instance_names(lidar)
    assert "Spawner" in names and "Post" not in names


def test_particle_emitter_hidden_in_render_is_not_scanned(scene):
    emitter = mesh_object("Emitter", [(6, -3, 0), (6, 3, 0), (6, 3, 4), (6, -3, 4)],
                          [(0, 1, 2, 3)])
    proto = mesh_object("Proto", [(0, -0.2, 0), (0, 0.2, 0), (0, 0.2, 0.4), (0, -0.2, 0.4)],
                        [(0, 1, 2, 3)])
    proto.location = (0, 30, 0)
    ps = emitter.modifiers.new("P", "PARTICLE_SYSTEM").particle_system.settings
    ps.count, ps.frame_start, ps.frame_end = 10, 1, 1
    ps.physics_type, ps.render_type, ps.instance_object = "NO", "OBJECT", proto
    emitter.show_instancer_for_render = False
    scene.frame_set(1)
    p, names = instance_names(add_lidar(location=(0, 0, 2)))
    assert "Emitter" not in names
    assert any(n.startswith("Emitter/Proto#") for n in names)


def test_collection_instancer_hidden_in_the_viewport_only_is_named(scene):
    """An empty instancing a collection, with its monitor icon off and its camera on: a
    render shows the collection's objects, the viewport's depsgraph has none of them.
    The scan said nothing of it (an audit's finding); it is named now, as a hidden
    mesh is."""
    from rls_addon.blender.read_rules import (
        hidden_in_viewport,
        hidden_in_viewport_warning,
    )

    kit = bpy.data.collections.new("Kit")  # not linked to the scene: instanced only
    post = mesh_object("KitPost", [(0, -0.3, 0), (0, 0.3, 0), (0, 0.3, 2), (0, -0.3, 2)],
                       [(0, 1, 2, 3)])
    scene.collection.objects.unlink(post)
    kit.objects.link(post)
    spot = bpy.data.objects.new("Spot", None)
    spot.instance_type, spot.instance_collection = "COLLECTION", kit
    spot.location = (5, 0, 0)
    scene.collection.objects.link(spot)
    ground()
    lidar = add_lidar(location=(0, 0, 1))
    _, names = instance_names(lidar)
    assert sum(n.startswith("Spot/KitPost") for n in names) > 50
    spot.hide_viewport = True  # the monitor icon: a render still shows the post
    assert hidden_in_viewport(bpy.context.evaluated_depsgraph_get()) == ["Spot"]
    result = scan(lidar)[0]
    assert not any(n.startswith("Spot") for n in instance_names(lidar)[1])
    assert result.warnings[0] == hidden_in_viewport_warning(["Spot"])
    spot.hide_render = True  # out of renders too: nothing to say
    assert scan(lidar)[0].warnings == []
    # an empty that instances nothing is no geometry, hidden or not
    spot.hide_render, spot.instance_type = False, "NONE"
    assert hidden_in_viewport(bpy.context.evaluated_depsgraph_get()) == []
