"""Reading meshes in bulk: the attribute-array reads give exactly what Blender's own
per-triangle accessors give, and a scan session reads an unchanged mesh once."""

import bpy
import numpy as np
import pytest

from .conftest import add_lidar, mesh_object


def reference(obj):
    """What Blender's per-item accessors give (the slow, plain way)."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    mesh = ev.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.array([tuple(v.co) for v in mesh.vertices], np.float64).reshape(-1, 3)
        tri = np.array([tuple(t.vertices) for t in mesh.loop_triangles], np.int64).reshape(-1, 3)
        mat = np.array([t.material_index for t in mesh.loop_triangles], np.int32)
        return co, tri, mat
    finally:
        ev.to_mesh_clear()


def read(obj):
    from rls_addon.blender.extract import read_mesh

    return read_mesh(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))


def materials(obj, n):
    for k in range(n):
        obj.data.materials.append(bpy.data.materials.new(f"{obj.name} m{k}"))


def test_triangles_quads_ngons_and_materials_read_as_blender_gives_them(scene):
    tris = mesh_object("Tris", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0.5)],
                       [(0, 1, 2), (1, 3, 2)])
    quads = mesh_object("Quads", [(x, y, 0.1 * x * y) for y in range(4) for x in range(4)],
                        [(y * 4 + x, y * 4 + x + 1, y * 4 + x + 5, y * 4 + x + 4)
                         for y in range(3) for x in range(3)])
    ring = [(np.cos(a), np.sin(a), 0.2 * np.sin(3 * a)) for a in np.linspace(0, 6, 7)]
    mixed = mesh_object("Mixed", ring + [(0, 0, 2)],
                        [tuple(range(7)), (0, 1, 7), (1, 2, 7, ), (3, 4, 7)])
    materials(quads, 3)
    for k, p in enumerate(quads.data.polygons):
        p.material_index = k % 3
    materials(mixed, 2)
    mixed.data.polygons[0].material_index = 1
    bpy.ops.object.text_add()
    text = bpy.context.object
    text.data.body = "RLS"
    for obj in (tris, quads, mixed, text):
        got, want = read(obj), reference(obj)
        assert np.array_equal(got[0], want[0]), obj.name
        assert np.array_equal(got[1], want[1]), obj.name
        assert np.array_equal(got[2], want[2]), obj.name
        assert len(got[1]) > 1
    assert set(read(quads)[2]) == {0, 1, 2}


def test_a_session_reads_an_unchanged_mesh_once(scene):
    from rls_addon.blender.extract import MeshReader, read_instances

    quads = mesh_object("Quads", [(x, y, 0) for y in range(3) for x in range(3)],
                        [(y * 3 + x, y * 3 + x + 1, y * 3 + x + 4, y * 3 + x + 3)
                         for y in range(2) for x in range(2)])
    tris = mesh_object("Tris", [(0, 0, 1), (1, 0, 1), (0, 1, 1)], [(0, 1, 2)])
    reader = MeshReader()

    def ids():
        dg = bpy.context.evaluated_depsgraph_get()
        return {i.key: i.mesh_id for i in read_instances(dg, reader=reader)[0]}

    first = ids()
    assert reader.reads == 2 and ids() == first and reader.reads == 2  # nothing changed
    quads.data.vertices[4].co.z = 0.5  # an edit: read again, with a new id
    quads.data.update()
    second = ids()
    assert reader.reads == 3 and second["Quads"] != first["Quads"]
    assert second["Tris"] == first["Tris"]
    materials(tris, 2)
    tris.data.polygons[0].material_index = 1  # a material change is a change too
    tris.data.update()
    assert ids()["Tris"] != first["Tris"] and reader.reads == 4
    # the same positions and corner sequence grouped into other faces: (3, 4) corners
    # against (4, 3) corners are other triangles, so the mesh is read again
    pts = [(np.cos(a), np.sin(a), 0.1 * a) for a in np.linspace(0, 5, 7)]
    a = mesh_object("Groups", pts, [(0, 1, 2), (3, 4, 5, 6)])
    other = mesh_object("Other", pts, [(0, 1, 2, 3), (4, 5, 6)])
    before = ids()["Groups"]
    a.data = other.data
    bpy.data.objects.remove(other)
    after = ids()["Groups"]
    assert after != before
    dg = bpy.context.evaluated_depsgraph_get()
    inst = [i for i in read_instances(dg, reader=reader)[0] if i.key == "Groups"][0]
    assert np.array_equal(inst.triangles, reference(a)[1])


def test_an_animated_modifier_is_read_every_frame(scene):
    from rls_addon.blender.extract import MeshReader, read_instances

    grid = mesh_object("Grid", [(x, y, 0) for y in range(5) for x in range(5)],
                       [(y * 5 + x, y * 5 + x + 1, y * 5 + x + 6, y * 5 + x + 5)
                        for y in range(4) for x in range(4)])
    wave = grid.modifiers.new("Wave", "WAVE")
    wave.height = 0.5
    reader = MeshReader()
    seen = []
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        dg = bpy.context.evaluated_depsgraph_get()
        inst = read_instances(dg, reader=reader)[0][0]
        seen.append(inst.vertices[:, 2].copy())
        assert np.array_equal(inst.vertices, reference(grid)[0])
    assert reader.reads == 3
    assert not np.array_equal(seen[0], seen[2])


@pytest.mark.parametrize("backend", ["bvhtree", "embree"])
def test_a_still_lidar_builds_its_static_scene_once(scene, backend):
    """Over frames of a static scene, the session neither reads the meshes again nor
    joins and digests the static geometry again; an edit is seen in the next frame."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.scan import session as scan_module
    from rls_addon.core.casting import caster_factory

    wall = mesh_object("Wall", [(5, -5, -3), (5, 5, -3), (5, 5, 5), (5, -5, 5)],
                       [(0, 1, 2, 3)])
    mesh_object("Ground", [(-9, -9, -2), (9, -9, -2), (9, 9, -2), (-9, 9, -2)], [(0, 1, 2, 3)])
    lidar = add_lidar()
    lidar.rls_lidar.frame_space = "world"
    session = scan_module.ScanSession(caster_factory(backend)[0])
    source = BlenderScene(scene)
    joins = []
    join = scan_module.world_geometry

    def counting(*a, **k):
        joins.append(1)
        return join(*a, **k)

    scan_module.world_geometry = counting
    try:
        xs = []
        for frame in (1, 2, 3):
            res, info = scan_lidar(lidar, frame, session=session, source=source)
            xs.append(wall_x(res.points))
        assert session.builds == 1 and len(joins) == 1 and source.meshes.reads == 2
        assert res.stats["static_cast_reused"] and "static_cast_reused" not in info
        for v in wall.data.vertices:
            v.co.x = 6.0
        wall.data.update()
        res, info = scan_lidar(lidar, 4, session=session, source=source)
    finally:
        scan_module.world_geometry = join
    assert session.builds == 2 and len(joins) == 2 and source.meshes.reads == 3
    assert not res.stats["static_cast_reused"]
    assert xs[0] == pytest.approx(5.0, abs=1e-6) and xs[0] == xs[1] == xs[2]
    assert wall_x(res.points) == pytest.approx(6.0, abs=1e-6)


def wall_x(points):
    """The wall's points (above the ground at z = -2): their largest x."""
    return points["x"][points["z"] > -1.9].max()


def test_without_attribute_arrays_every_item_is_read(scene, monkeypatch):
    """A Blender without the attribute arrays (positions, corners) is read item by
    item, to the same result, and never taken for unchanged."""
    from rls_addon.blender import extract

    quads = mesh_object("Quads", [(x, y, 0.2 * x) for y in range(3) for x in range(3)],
                        [(y * 3 + x, y * 3 + x + 1, y * 3 + x + 4, y * 3 + x + 3)
                         for y in range(2) for x in range(2)])
    fast = read(quads)
    monkeypatch.setattr(extract, "_attribute_arrays", lambda mesh: None)
    slow = read(quads)
    for a, b, c in zip(fast, slow, reference(quads)):
        assert np.array_equal(a, b) and np.array_equal(b, c)
    reader = extract.MeshReader()
    dg = bpy.context.evaluated_depsgraph_get()
    extract.read_instances(dg, reader=reader)
    extract.read_instances(dg, reader=reader)
    assert reader.reads == 2


def test_an_unedited_file_is_read_once_while_nothing_but_the_lidar_moves(scene):
    """The command line's source (``edited=False``) keeps its read from one anchor and
    range while nothing in the file but LiDARs can change over time; anything animated
    (an object, a material) or a modifier that changes by itself means a read per
    frame, and so does Blender's interface (``edited=True``)."""
    from rls_addon.blender.motion import timeless
    from rls_addon.blender.source import BlenderScene

    wall = mesh_object("Wall", [(5, -5, -3), (5, 5, -3), (5, 5, 5), (5, -5, 5)],
                       [(0, 1, 2, 3)])
    lidar = add_lidar()
    lidar.keyframe_insert("location", frame=1)
    lidar.location.x = 1.0
    lidar.keyframe_insert("location", frame=5)

    def reads(source, frames=(1, 2, 3)):
        before, got = source.meshes.reads, []
        for f in frames:
            scene.frame_set(f)
            got.append(source.read(np.zeros(3), 50.0, {lidar.name}))
        return source.meshes.reads - before, got

    count, got = reads(BlenderScene(scene, edited=False))
    assert timeless(bpy.data) and got[0] is got[1] is got[2] and count == 1
    assert reads(BlenderScene(scene))[1][0] is not reads(BlenderScene(scene))[1][0]
    child = mesh_object("Child", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    child.parent = lidar  # moves with the lidar
    assert not timeless(bpy.data)
    child.parent = None
    assert timeless(bpy.data)
    wall.data.materials.append(bpy.data.materials.new("Paint"))
    wall.data.materials[0].keyframe_insert("diffuse_color", frame=1)
    assert not timeless(bpy.data)
    count, got = reads(BlenderScene(scene, edited=False))
    assert got[0] is not got[1] and count == 2  # read each frame (meshes still reused)
    wall.data.materials[0].animation_data_clear()
    wall.modifiers.new("Build", "BUILD")
    assert not timeless(bpy.data)


def test_an_unedited_files_fixed_meshes_are_not_evaluated_again(scene, monkeypatch):
    """The command line's source (``edited=False``) gives back a mesh it read before
    without evaluating it again where it cannot change (``mesh_is_fixed``): a plain
    mesh moving by its object's animation; a mesh with a modifier, shape keys, an
    animated mesh or a lattice parent is evaluated each frame, and what it reads is
    what Blender evaluates at that frame."""
    import bpy

    from rls_addon.blender.extract import read_instances
    from rls_addon.blender.motion import mesh_is_fixed
    from rls_addon.blender.source import BlenderScene

    def quad(name, z):
        return mesh_object(name, [(0, 0, z), (1, 0, z), (1, 1, z), (0, 1, z)], [(0, 1, 2, 3)])

    mover = quad("Mover", 0.0)
    mover.keyframe_insert("location", frame=1)
    mover.location.x = 3.0
    mover.keyframe_insert("location", frame=3)
    keyed = quad("Keyed", 1.0)
    keyed.shape_key_add(name="Basis")
    up = keyed.shape_key_add(name="Up")
    for v in up.data:
        v.co.z += 2.0
    up.value = 0.0
    up.keyframe_insert("value", frame=1)
    up.value = 1.0
    up.keyframe_insert("value", frame=3)
    waved = quad("Waved", 2.0)
    waved.modifiers.new("Wave", "WAVE")
    lattice = bpy.data.objects.new("Lattice", bpy.data.lattices.new("Lattice"))
    scene.collection.objects.link(lattice)
    bent = quad("Bent", 3.0)
    bent.parent, bent.parent_type = lattice, "LATTICE"
    assert mesh_is_fixed(mover)
    assert not any(mesh_is_fixed(o) for o in (keyed, waved, bent))
    from rls_addon.blender import extract

    evaluated, real, reading = [], extract._read, [False]
    monkeypatch.setattr(extract, "_read", lambda ob, known=None: (
        reading[0] and evaluated.append((frame, ob.original.name)), real(ob, known))[1])
    source = BlenderScene(scene, edited=False)
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        reading[0] = True
        got = {i.key: i for i in source.read(np.zeros(3), 1e6, set()).instances}
        reading[0] = False
        dg = bpy.context.evaluated_depsgraph_get()
        want = {i.key: i for i in read_instances(dg)[0]}
        for key in ("Mover", "Keyed", "Waved", "Bent"):
            assert np.array_equal(got[key].vertices, want[key].vertices), (key, frame)
            assert np.array_equal(got[key].matrix, want[key].matrix), (key, frame)
    assert got["Keyed"].vertices[:, 2].max() == pytest.approx(3.0)  # the shape key moved it
    # after the first frame only the meshes that may change were evaluated again
    assert {n for f, n in evaluated if f > 1} == {"Keyed", "Waved", "Bent"}
    assert ("Mover", 1) in {(n, f) for f, n in evaluated}


def test_every_objects_distance_at_once_is_each_objects_own():
    """``_bounds_distances`` (every object's bounds against the sensor in one product)
    gives each object's ``_bounds_distance`` exactly; a bound or matrix with a NaN or
    an infinity is 0 (read), as one by one."""
    from rls_addon.blender.extract import _bounds_distance, _bounds_distances

    rng = np.random.default_rng(3)
    n = 500
    corners = rng.normal(0, 4, (n, 8, 3)).astype(np.float32).astype(np.float64)
    mats = np.tile(np.eye(4), (n, 1, 1))
    mats[:, :3, :] = rng.normal(0, 1, (n, 3, 4)) * [1.0, 1.0, 1.0, 120.0]
    corners[7, 3, 1], mats[11, 0, 3], corners[13, 0, 0] = np.nan, np.inf, -np.inf
    centre = np.array([4.0, -3.0, 1.5])
    got = _bounds_distances(mats, corners, centre)
    want = [_bounds_distance(m, [tuple(c) for c in cs], centre) for m, cs in zip(mats, corners)]
    assert got.tolist() == want
    assert got[7] == got[11] == got[13] == 0.0 and np.count_nonzero(got) > n // 2


def test_an_unedited_read_culls_and_labels_as_a_plain_read(scene):
    """The source of a file nobody edits looks each object's label up once (``labels``)
    and culls every object by its bounds at once: its reads, over frames of a car
    driving out of range, are what a plain read gives (keys, labels, matrices, the
    counts of culled and hidden objects), an object instanced by two labelled
    instancers keeping each one's label."""
    from rls_addon.blender.extract import read_instances

    vehicles = bpy.data.collections.new("Vehicles")
    scene.collection.children.link(vehicles)
    car = mesh_object("Car", [(0, 0, 0), (4, 0, 0), (0, 2, 0)], [(0, 1, 2)],
                      collection=vehicles)
    for frame, x in ((1, 0.0), (5, 80.0)):
        car.location.x = x
        car.keyframe_insert("location", frame=frame)
    mesh_object("Wall", [(5, -5, 0), (5, 5, 0), (5, 5, 4)], [(0, 1, 2)])
    mesh_object("Far", [(90, 0, 0), (91, 0, 0), (90, 1, 0)], [(0, 1, 2)])
    mesh_object("Hidden", [(1, 1, 0), (2, 1, 0), (1, 2, 0)], [(0, 1, 2)]).hide_render = True
    props = bpy.data.collections.new("Props")  # instanced twice, by differently labelled empties
    mesh_object("Cone", [(0, 0, 0), (0.3, 0, 0), (0, 0.3, 0.5)], [(0, 1, 2)], collection=props)
    for name, label, x in (("Walker", "pedestrian", 3.0), ("Rider", "cyclist", -3.0)):
        empty = bpy.data.objects.new(name, None)
        empty.instance_type, empty.instance_collection = "COLLECTION", props
        empty.location.x, empty["rls_label"] = x, label
        scene.collection.objects.link(empty)
    labels = {}
    seen = set()
    for frame in (1, 3, 5):
        scene.frame_set(frame)
        dg = bpy.context.evaluated_depsgraph_get()
        kept = read_instances(dg, np.zeros(3), 50.0, labels=labels)
        plain = read_instances(dg, np.zeros(3), 50.0)
        assert kept[2] == plain[2]
        assert [(i.key, i.label, i.matrix.tobytes()) for i in kept[0]] == \
            [(i.key, i.label, i.matrix.tobytes()) for i in plain[0]]
        seen |= {(i.source, i.label) for i in kept[0]}
        assert kept[2]["hidden"] == 1 and kept[2]["culled_by_range"] == (2 if frame == 5 else 1)
    from rls_addon.core.labels import label_id
    assert {("Cone", label_id("pedestrian")), ("Cone", label_id("cyclist")),
            ("Car", label_id("vehicle"))} <= seen
