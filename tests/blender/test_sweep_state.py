"""The scene at a sub-frame time (``blender/motion.read_state``): with no object to
follow, the sensor is read straight from the depsgraph, the matrix the walk over every
instance finds (a LiDAR driving and turning over a still scene); with objects to
follow and no instances beside the objects, every matrix in one call, the ones the
walk finds (``_walk_state``, the reference)."""

import bpy
import numpy as np

from rls_addon.blender.motion import SweepClock, _object_matrices, _walk_state, read_state

from rls_addon.blender.extract import instance_key

from .conftest import add_lidar, mesh_object


def test_the_sensor_alone_is_read_as_the_walk_reads_it(scene):
    mesh_object("Box", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    lidar = add_lidar(location=(0, 0, 2))
    for frame, x, yaw in ((1, 0.0, 0.0), (11, 10.0, 0.7)):
        lidar.location.x, lidar.rotation_euler.z = x, yaw
        lidar.keyframe_insert("location", frame=frame)
        lidar.keyframe_insert("rotation_euler", frame=frame)
    clock = SweepClock(scene, 4, 0.1)
    for t in (0.0, 0.0123, 0.05, 0.1):
        clock.set(t)
        dg = bpy.context.evaluated_depsgraph_get()
        mats, verts, alone = read_state(dg, set(), set(), lidar.name)
        _, _, walked = _walk_state(dg, {"no such object"}, set(), lidar.name)
        assert mats == {} and verts == {}
        assert alone.tobytes() == walked.tobytes()
        assert alone[0, 3] > 0.0
    clock.restore()
    assert read_state(bpy.context.evaluated_depsgraph_get(), set(), set(), "Gone")[2] is None


def test_every_matrix_in_one_call_is_the_one_the_walk_reads(scene):
    """Moving, turning, accelerating, scaled and parented objects and a turning LiDAR
    at times across a sweep (sub-frames, the seam at the next frame's start): the
    matrices read in one call are the walk's, byte for byte, with the same keys; a
    collection instance beside them (an instance that is not an object itself) sends
    the read back to the walk, which alone names it."""
    car, lidar = _animated_street(scene)
    car.scale = (1.0, 2.0, 0.5)
    still = mesh_object("Still", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    still.location = (3.0, -4.0, 0.25)
    trailer = mesh_object("Trailer", [(0, 0, 0), (2, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    trailer.parent, trailer.location = car, (-3.0, 0.5, 0.0)
    keys = {"Car", "Trailer", "Still", "Gone"}

    def both(frame, subframe):
        scene.frame_set(frame, subframe=subframe)
        dg = bpy.context.evaluated_depsgraph_get()
        return dg, read_state(dg, keys, set(), lidar.name), _walk_state(dg, keys, set(), lidar.name)

    seen = set()
    for frame, subframe in ((3, 0.0), (3, 0.125), (3, 0.5), (3, 0.875), (4, 0.0), (7, 0.3)):
        dg, (mats, verts, sensor), (ref, _, ref_sensor) = both(frame, subframe)
        assert _object_matrices(dg) is not None  # the one call was taken
        assert sorted(mats) == sorted(ref) == ["Car", "Still", "Trailer"] and verts == {}
        for k in ref:
            assert mats[k].dtype == np.float64 and mats[k].tobytes() == ref[k].tobytes()
        assert sensor.tobytes() == ref_sensor.tobytes()
        seen.add(mats["Trailer"].tobytes())
    assert len(seen) == 6  # the trailer moves with its parent at every time
    # a collection instance: the walk, which alone knows its key
    group = bpy.data.collections.new("Group")
    group.objects.link(mesh_object("Cone", [(0, 0, 0), (1, 0, 0), (0, 0, 1)], [(0, 1, 2)]))
    holder = bpy.data.objects.new("Holder", None)
    holder.instance_type, holder.instance_collection = "COLLECTION", group
    scene.collection.objects.link(holder)
    dg, (mats, _, sensor), (ref, _, ref_sensor) = both(5, 0.5)
    assert _object_matrices(dg) is None
    names = [instance_key(i) for i in dg.object_instances if i.is_instance]
    keys.update(names)
    dg, (mats, _, sensor), (ref, _, ref_sensor) = both(5, 0.5)
    assert names and set(mats) == set(ref) and set(names) <= set(mats)
    assert all(mats[k].tobytes() == ref[k].tobytes() for k in ref)


class _Counting:
    """A scene that counts its frame changes (everything else is the scene's)."""

    def __init__(self, scene):
        self.__dict__["_scene"], self.__dict__["sets"] = scene, []

    def frame_set(self, frame, subframe=0.0):
        self.sets.append((frame, subframe))
        self._scene.frame_set(frame, subframe=subframe)

    def __getattr__(self, name):
        return getattr(self._scene, name)


def _animated_street(scene):
    scene.render.fps, scene.render.fps_base = 10, 1.0  # a sweep of 0.1 s: one frame
    car = mesh_object("Car", [(0, 0, 0), (4, 0, 0), (0, 2, 0), (0, 0, 1.5)],
                      [(0, 1, 2), (0, 1, 3)])
    lidar = add_lidar(location=(0, 0, 2))
    for frame, x, yaw in ((1, 0.0, 0.0), (6, 3.0, 0.4), (11, 12.0, 1.1)):  # eased: accelerating
        for obj, dx in ((car, 5.0), (lidar, 0.0)):
            obj.location.x, obj.rotation_euler.z = x + dx, yaw
            obj.keyframe_insert("location", frame=frame)
            obj.keyframe_insert("rotation_euler", frame=frame)
    return car, lidar


def _states(source, frame, times, keys, sensor):
    source.set_frame(frame)
    with source.sweep(frame, 0.1) as sweep:
        # the clock sets the scene itself, or through the source's SceneTime
        at = sweep.clock.at
        counting = sweep.clock.scene = _Counting(sweep.clock.scene)
        if at is not None:
            at.scene = counting
        try:
            got = [sweep.state(t, keys, set(), sensor) for t in times]
        finally:
            if at is not None:
                at.scene = counting._scene
    return got, counting.sets


def test_an_unedited_sweep_reads_what_setting_every_time_reads(scene):
    """An unedited source (a background run) does not set the scene again at the
    sweep's start, where the run has just set it, and gives the state a sweep read at
    its end back at the next frame's start (``motion.SceneTime``); every state it
    reads, over frames of an accelerating, turning car and LiDAR, is the one a source
    that sets and reads every time reads, byte for byte."""
    from rls_addon.blender.source import BlenderScene

    _, lidar = _animated_street(scene)
    times = [0.0, 0.05, 0.1, 0.025, 0.075]
    unedited, edited = BlenderScene(scene, edited=False), BlenderScene(scene)
    assert unedited.time() is not None and edited.time() is None
    for frame in (3, 4, 7):
        fast, fast_sets = _states(unedited, frame, times, {"Car"}, lidar.name)
        assert unedited.time().owed == frame and scene.frame_subframe == 0.75
        slow, slow_sets = _states(edited, frame, times, {"Car"}, lidar.name)
        # every time set but the start; the way back to the frame owed (not yet set)
        assert fast_sets == [(frame, 0.5), (frame + 1, 0.0), (frame, 0.25), (frame, 0.75)]
        assert slow_sets == [(frame, 0.0)] + fast_sets + [(frame, 0.0)]
        for (m1, _, s1), (m2, _, s2) in zip(fast, slow):
            assert m1["Car"].tobytes() == m2["Car"].tobytes()
            assert s1.tobytes() == s2.tobytes()
        assert len({m["Car"].tobytes() for m, _, _ in fast}) == len(times)  # it moves
        # frame 4 starts where frame 3's sweep ended: that state is given back (kept
        # read-only), not read again; frame 7 follows no sweep that ended there
        assert fast[0][0]["Car"].flags.writeable == (frame != 4)
        assert fast[0][2].flags.writeable == (frame != 4)


def test_a_scene_stepped_from_frame_to_frame_is_set_at_every_time(scene):
    """A geometry-nodes modifier (a simulation zone steps from frame to frame) or a
    rigid body anywhere: the source keeps no ``SceneTime`` and sets every time."""
    from rls_addon.blender.source import BlenderScene

    car, lidar = _animated_street(scene)
    assert BlenderScene(scene, edited=False).time() is not None
    mod = car.modifiers.new("nodes", "NODES")
    source = BlenderScene(scene, edited=False)
    assert source.time() is None
    _, sets = _states(source, 3, [0.0, 0.05], {"Car"}, lidar.name)
    assert sets[0] == (3, 0.0)
    car.modifiers.remove(mod)
    bpy.context.view_layer.objects.active = car
    car.select_set(True)
    bpy.ops.rigidbody.object_add()
    assert BlenderScene(scene, edited=False).time() is None


def test_a_sweep_owes_its_way_back_until_the_scene_is_read(scene):
    """An unedited source's sweep that ends at the next frame's start (its last state
    read there, as ``sweep.sample_sweep`` reads) leaves the scene there: going on to
    that frame sets nothing, and reading the scene first puts it back at the sweep's
    frame (``SceneTime.settle``), as Blender's interface always has it."""
    from rls_addon.blender.source import BlenderScene

    _, lidar = _animated_street(scene)
    source = BlenderScene(scene, edited=False)
    # the sweep's end last: the scene is at frame 4 when the sweep is left
    _, sets = _states(source, 3, [0.0, 0.05, 0.025, 0.1], {"Car"}, lidar.name)
    assert sets == [(3, 0.5), (3, 0.25), (4, 0.0)]
    assert scene.frame_current == 4 and source.time().owed == 3
    source.set_frame(4)  # where the run goes next: already there, nothing to set
    assert source.time().owed is None and scene.frame_current == 4
    _, sets = _states(source, 4, [0.0, 0.05], {"Car"}, lidar.name)
    assert sets == [(4, 0.5)] and scene.frame_subframe == 0.5
    assert source.current_frame() == 4 and scene.frame_subframe == 0.0  # settled
    want = np.array(bpy.data.objects["Car"].matrix_world)  # the frame's own matrix
    scene.frame_set(4)
    assert np.array_equal(want, np.array(bpy.data.objects["Car"].matrix_world))
    _states(source, 4, [0.0, 0.05], {"Car"}, lidar.name)
    pose = source.sensor_pose(lidar.name)  # a read settles too
    assert scene.frame_subframe == 0.0
    scene.frame_set(4)
    assert np.array_equal(pose, source.sensor_pose(lidar.name))
