"""What RLS assumes of a Blender scene, checked where it is read.

Names: RLS tells objects and materials apart by name, and names are unique only within
one file. Two of one name (a linked one beside a local one) are refused with both full
names, never read as one (before the check, a linked sphere named like a local cube was
scanned as the cube); linked objects of names of their own are read as they are.

Units: Blender units are read as metres; a scene whose Unit Scale is not 1 is refused
(it would be scanned at the wrong size), whatever units it only shows."""

import bpy
import numpy as np
import pytest

from rls_addon.core.errors import SceneError

from .conftest import add_lidar, ground, mesh_object, scan


def library(path, build):
    """Save a file holding what ``build()`` makes, then start an empty one again."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)


def link(path, *names):
    """Link objects ``names`` from the file at ``path`` into the scene."""
    with bpy.data.libraries.load(str(path), link=True) as (_, dst):
        dst.objects = list(names)
    for ob in dst.objects:
        bpy.context.scene.collection.objects.link(ob)
    return dst.objects


def sphere(name, location):
    bpy.ops.mesh.primitive_uv_sphere_add(location=location)
    bpy.context.object.name = name
    return bpy.context.object


def cube(name, location):
    bpy.ops.mesh.primitive_cube_add(location=location)
    bpy.context.object.name = name
    return bpy.context.object


def read():
    from rls_addon.blender.extract import read_instances

    return read_instances(bpy.context.evaluated_depsgraph_get())


def test_a_linked_object_named_as_a_local_one_is_refused(scene, tmp_path):
    lib = tmp_path / "cars.blend"
    library(lib, lambda: sphere("Car", (10, 0, 1)))
    add_lidar(location=(0, 0, 1.5))
    ground()
    cube("Car", (0, 10, 1))
    (linked,) = link(lib, "Car")
    assert linked.library is not None and linked.name == "Car"
    with pytest.raises(SceneError, match=r"two objects are named 'Car' \('Car' and "
                                         r"'Car \[cars\.blend\]'.*rename one of them"):
        read()
    # a scan says so too, and makes no points of the cube where the sphere stands
    with pytest.raises(SceneError, match="two objects are named 'Car'"):
        scan(bpy.data.objects["LiDAR"])


def test_a_hidden_namesake_is_refused_too(scene, tmp_path):
    # not read, but its matrix has its name: a sweep would take it for the visible one's
    lib = tmp_path / "hidden.blend"

    def build():
        sphere("Car", (10, 0, 1)).hide_render = True

    library(lib, build)
    cube("Car", (0, 10, 1))
    link(lib, "Car")
    with pytest.raises(SceneError, match="two objects are named 'Car'"):
        read()


def test_materials_of_one_name_from_two_files_are_refused(scene, tmp_path):
    lib = tmp_path / "signs.blend"

    def build():
        sign = cube("Sign", (10, 0, 1))
        mat = bpy.data.materials.new("Paint")
        mat["rls_reflectivity"] = 0.9
        sign.data.materials.append(mat)

    library(lib, build)
    wall = mesh_object("Wall", [(0, 5, 0), (2, 5, 0), (2, 5, 2), (0, 5, 2)], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new("Paint")
    mat["rls_reflectivity"] = 0.1
    wall.data.materials.append(mat)
    link(lib, "Sign")
    with pytest.raises(SceneError, match=r"two materials are named 'Paint' \('Paint' and "
                                         r"'Paint \[signs\.blend\]'"):
        read()


def test_linked_objects_of_their_own_names_are_read_as_they_are(scene, tmp_path):
    lib = tmp_path / "props.blend"
    library(lib, lambda: sphere("Ball", (10, 0, 1)))
    local = cube("Box", (0, 10, 1))
    (linked,) = link(lib, "Ball")
    got = {i.key: i for i in read()[0]}
    assert set(got) == {"Ball", "Box"}
    assert len(got["Box"].vertices) == len(local.data.vertices) == 8
    assert len(got["Ball"].vertices) == len(linked.data.vertices) > 8
    assert np.allclose(got["Ball"].matrix[:3, 3], (10, 0, 1))


@pytest.mark.parametrize("scale, size", [(0.01, "100 times too large"),
                                         (1000.0, "1000 times too small")])
def test_a_scene_not_in_metres_is_refused(scene, scale, size):
    # Blender units are read as metres: at a Unit Scale of 0.01 a 4.5 m car modelled as
    # 450 units would be scanned as a 450 m one
    add_lidar(location=(0, 0, 1.5))
    ground()
    scene.unit_settings.scale_length = scale
    with pytest.raises(SceneError, match=rf"Unit Scale of {scale:g} .*{size}.*Unit Scale 1"):
        read()
    with pytest.raises(SceneError, match="Unit Scale"):
        scan(bpy.data.objects["LiDAR"])
    scene.unit_settings.scale_length = 1.0  # metres, whatever units it shows
    scene.unit_settings.system = "IMPERIAL"
    assert len(read()[0]) == 1 and len(scan(bpy.data.objects["LiDAR"])[0].points) > 1000


def test_objects_hidden_in_the_viewport_but_not_from_render_are_named(scene, tmp_path):
    # The viewport's depsgraph leaves them out, so they are not scanned: a scan says so
    from rls_addon.blender.read_rules import hidden_in_viewport, hidden_in_viewport_warning

    lidar = add_lidar(location=(0, 0, 1.5))
    ground()
    eye = cube("Eye", (5, 0, 1))
    monitor = cube("Monitor", (0, 5, 1))
    both = cube("Gone", (-5, 0, 1))
    inner = bpy.data.collections.new("Inner")
    scene.collection.children.link(inner)
    kept = cube("InHidden", (0, -5, 1))
    scene.collection.objects.unlink(kept)
    inner.objects.link(kept)
    assert len(scan(lidar)[0].warnings) == 0
    # a collection's eye in the view layer hides it on screen, but the depsgraph keeps
    # its objects: they are scanned, and nothing is said
    bpy.context.view_layer.layer_collection.children["Inner"].hide_viewport = True
    result, info = scan(lidar)
    assert result.warnings == [] and "InHidden" in {o["object"] for o in info["labels"].values()}
    bpy.context.view_layer.layer_collection.children["Inner"].hide_viewport = False
    eye.hide_set(True)                       # the eye: hidden in this view layer
    monitor.hide_viewport = True             # the monitor: disabled in viewports
    both.hide_viewport = both.hide_render = True   # out of renders too: no word of it
    inner.hide_viewport = True               # its collection disabled in viewports
    names = hidden_in_viewport(bpy.context.evaluated_depsgraph_get())
    assert names == ["Eye", "InHidden", "Monitor"]
    result, info = scan(lidar)
    assert result.warnings[0] == hidden_in_viewport_warning(names)
    assert "3 objects hidden in the viewport but not from render are not scanned" \
        in result.warnings[0] and "'Eye', 'InHidden', 'Monitor'" in result.warnings[0]
    labels = {o["object"] for o in info["labels"].values()}
    assert labels.isdisjoint({"Eye", "Monitor", "InHidden", "Gone"})
    # a placement study's static read says it too (its notices)
    from rls_addon.blender.study import BlenderStudyScene

    study_scene = BlenderStudyScene(scene)
    study_scene.static_geometry(set())
    assert study_scene.warnings == [hidden_in_viewport_warning(names)]
    # excluded from the view layer, or its collection out of renders: a render would
    # not show it either
    bpy.context.view_layer.layer_collection.children["Inner"].exclude = True
    eye.hide_set(False)
    monitor.hide_render = True
    assert hidden_in_viewport(bpy.context.evaluated_depsgraph_get()) == []
    assert scan(lidar)[0].warnings == []
    assert hidden_in_viewport_warning(["A"]).startswith(
        "1 object hidden in the viewport but not from render is not scanned ('A'): show it")
    assert "('a', 'b', 'c', 'd', 'e' and 2 more)" in hidden_in_viewport_warning(list("abcdefg"))


def test_modifiers_set_otherwise_for_render_are_named_in_a_warning(scene):
    """The read is the viewport's geometry (Python builds no render depsgraph): an audit
    found an Array modifier off in the viewport but on for render scanned as 1 post of
    3, and a Subdivision at viewport level 0, render level 3, 16 cm short. The scan
    says so, naming each such modifier; modifiers set alike say nothing."""
    from rls_addon.blender.extract import read_instances
    from rls_addon.blender.read_rules import read_warnings

    post = mesh_object("Post", [(5, -0.2, 0), (5, 0.2, 0), (5, 0.2, 3), (5, -0.2, 3)],
                       [(0, 1, 2, 3)])
    array = post.modifiers.new("Row", "ARRAY")
    array.relative_offset_displace = (0.0, 8.0, 0.0)
    array.count = 3
    smooth = mesh_object("Rock", [(8, 0, 0), (9, 0, 0), (9, 1, 0)], [(0, 1, 2)])
    sub = smooth.modifiers.new("Smooth", "SUBSURF")
    sub.levels = sub.render_levels = 1
    lidar = add_lidar()
    _, _, stats = read_instances(bpy.context.evaluated_depsgraph_get(), exclude={lidar.name})
    assert read_warnings(stats) == []
    array.show_viewport = False
    smooth.modifiers["Smooth"].render_levels = 3
    _, _, stats = read_instances(bpy.context.evaluated_depsgraph_get(), exclude={lidar.name})
    (warning,) = read_warnings(stats)
    assert warning.startswith("2 modifiers set otherwise for render than for the viewport "
                              "('Post' (Row), 'Rock' (Smooth)): RLS scans the viewport's")
    result, info = scan(lidar)
    assert any("set otherwise for render" in w for w in info["warnings"])
