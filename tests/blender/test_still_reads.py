"""Still objects' reads kept between frames (``blender/still_reads.py``): in a file
nobody edits, what a read made of an object that cannot change is given back at the
next read from the same place, and the read is the one a full read gives, object for
object and in the same order, while the traffic beside it moves, hides and changes
the material table."""

import bpy
import numpy as np

from rls_addon.blender.extract import read_instances
from rls_addon.blender.source import BlenderScene
from rls_addon.blender.motion import still_objects

from .conftest import add_lidar, mesh_object

QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def _material(name, reflectivity):
    mat = bpy.data.materials.new(name)
    mat["rls_reflectivity"] = reflectivity
    return mat


def _with_materials(obj, *mats):
    for m in mats:
        obj.data.materials.append(m)
    if len(mats) > 1:  # the second face on the second slot
        obj.data.polygons[-1].material_index = 1
    return obj


def _street(scene):
    """Traffic first in the walk (so it decides the material table's order), then still
    objects: two with materials in slots, one hidden from render, one far away, one
    with no face, one labelled a parked vehicle."""
    m1, m2, m3 = _material("M1", 0.3), _material("M2", 0.6), _material("M3", 0.9)
    car = _with_materials(mesh_object("Car", QUAD, [(0, 1, 2, 3)]), m2)
    car.location = (5, 0, 0)
    car.keyframe_insert("location", frame=1)
    car.hide_render = False
    car.keyframe_insert("hide_render", frame=1)
    car.location = (8, 0, 0)
    car.keyframe_insert("location", frame=3)
    car.hide_render = True
    car.keyframe_insert("hide_render", frame=3)
    two = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]
    wall = _with_materials(mesh_object("Wall", two, [(0, 1, 2, 3), (1, 4, 5, 2)]), m1, m2)
    wall.location = (0, 10, 0)
    sign = _with_materials(mesh_object("Sign", QUAD, [(0, 1, 2, 3)]), m3)
    sign.location = (0, -10, 0)
    hidden = mesh_object("Hidden", QUAD, [(0, 1, 2, 3)])
    hidden.hide_render = True
    far = mesh_object("Far", QUAD, [(0, 1, 2, 3)])
    far.location = (5000, 0, 0)
    mesh_object("Dots", [(0, 0, 0), (1, 0, 0)], [])
    parked = mesh_object("Parked", QUAD, [(0, 1, 2, 3)])
    parked["rls_label"] = "vehicle"
    parked.location = (0, 4, 0)
    lidar = add_lidar()
    return car, lidar


def _same_read(kept, fresh):
    (ki, km, ks), (fi, fm, fs) = kept, fresh
    assert [i.key for i in ki] == [i.key for i in fi]
    for a, b in zip(ki, fi):
        assert (a.source, a.parent, a.label) == (b.source, b.parent, b.label)
        for name in ("vertices", "triangles", "materials", "matrix", "slot_map"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (a.key, name)
    assert km == fm
    assert ks == fs


def test_a_kept_read_of_still_objects_is_the_full_read_frame_by_frame(scene):
    car, lidar = _street(scene)
    assert still_objects(bpy.data) == {"Wall", "Sign", "Hidden", "Far", "Dots", "Parked"}
    source = BlenderScene(scene, edited=False)
    remapped = False
    for frame in (1, 2, 3, 2, 1):
        scene.frame_set(frame)
        got = source.read(np.zeros(3), 100.0, {lidar.name})
        fresh = read_instances(bpy.context.evaluated_depsgraph_get(), centre=np.zeros(3),
                               max_range=100.0, exclude={lidar.name})
        _same_read((got.instances, got.materials, got.stats), fresh)
        keys = [i.key for i in got.instances]
        assert ("Car" in keys) == (frame < 3) and "Far" not in keys and "Hidden" not in keys
        assert got.stats["hidden"] == 1 + (frame >= 3) and got.stats["culled_by_range"] == 1
        wall = got.instances[keys.index("Wall")]
        remapped |= list(wall.slot_map) != [2, 1]  # M2 first when the car is read
    assert remapped  # the hidden car moved M1 and M2 in the table: the wall followed
    # the still objects' records were given back, not read again
    entries = source._still.at((np.zeros(3).tobytes(), 100.0, frozenset({lidar.name})))
    assert {n: e.kind for n, e in entries.items()} == {
        "Wall": "read", "Sign": "read", "Hidden": "hidden", "Far": "far", "Dots": "empty",
        "Parked": "read"}
    scene.frame_set(1)
    again = source.read(np.zeros(3), 100.0, {lidar.name})
    assert again.instances[[i.key for i in again.instances].index("Sign")] \
        is entries["Sign"].instance


def test_only_objects_nothing_can_change_are_still(scene):
    _street(scene)
    child = mesh_object("Child", QUAD, [(0, 1, 2, 3)])
    child.parent = bpy.data.objects["Sign"]
    bent = mesh_object("Bent", QUAD, [(0, 1, 2, 3)])
    bent.modifiers.new("bend", "SIMPLE_DEFORM")
    held = mesh_object("Held", QUAD, [(0, 1, 2, 3)])
    held.constraints.new("COPY_LOCATION").target = bpy.data.objects["Car"]
    names = still_objects(bpy.data)
    assert not {"Car", "Child", "Bent", "Held", "LiDAR"} & names and "Wall" in names
    # a material that changes over time may change any still object's read: none is still
    bpy.data.materials["M3"].diffuse_color = (1, 0, 0, 1)
    bpy.data.materials["M3"].keyframe_insert("diffuse_color", frame=1)
    assert still_objects(bpy.data) == frozenset()
    # and the user may edit a file open in Blender: every read reads
    assert BlenderScene(scene)._still_reads() is None
