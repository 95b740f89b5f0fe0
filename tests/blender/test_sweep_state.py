"""The scene at a sub-frame time (``blender/motion.read_state``): with no object to
follow, the sensor is read straight from the depsgraph, the matrix the walk over every
instance finds (a LiDAR driving and turning over a still scene)."""

import bpy
import numpy as np

from rls_addon.blender.motion import SweepClock, read_state

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
        _, _, walked = read_state(dg, {"no such object"}, set(), lidar.name)
        assert mats == {} and verts == {}
        assert alone.tobytes() == walked.tobytes()
        assert alone[0, 3] > 0.0
    clock.restore()
    assert read_state(bpy.context.evaluated_depsgraph_get(), set(), set(), "Gone")[2] is None
