"""BlenderScene.timeless: whether nothing in a scene changes over time, which lets the
cost model count a still LiDAR's frames as reuses of its first cast (issue 31)."""

from rls_addon.blender.source import BlenderScene

from .conftest import add_lidar, mesh_object


def test_a_scene_with_nothing_animated_is_timeless_and_one_key_is_not(scene):
    box = mesh_object("Box", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    lidar = add_lidar()
    assert BlenderScene(scene, edited=False).timeless()
    assert not BlenderScene(scene).timeless()  # the user may edit it: never
    box.keyframe_insert("location", frame=1)
    assert not BlenderScene(scene, edited=False).timeless()
    box.animation_data_clear()
    assert BlenderScene(scene, edited=False).timeless()
    source = BlenderScene(scene, edited=False)
    assert not source.sensor_may_move(lidar.name)
    # a turning LiDAR is no geometry of the scene: the scene stays timeless, and the
    # LiDAR is not still (ScanRun.still_sensors asks both)
    lidar.keyframe_insert("rotation_euler", frame=1)
    source = BlenderScene(scene, edited=False)
    assert source.timeless() and source.sensor_may_move(lidar.name)


def test_an_unedited_scenes_mobility_is_kept_and_given_as_a_copy(scene):
    """What may move is worked out once per objects read in an unedited file (it cannot
    change there); each call gets its own copy, equal to a fresh answer."""
    still = mesh_object("Still", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    car = mesh_object("Car", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    car.keyframe_insert("location", frame=1)
    lidar = add_lidar()
    source = BlenderScene(scene, edited=False)
    read = source.read(still.location, 1e6, {lidar.name})
    first = source.mobility(read.instances, lidar.name)
    keys = [read.instances[k].key for k in first.candidates]
    assert keys == ["Car"] and not first.sensor_moves
    first.candidates.append(0)
    first.deformable.add("Still")
    again = source.mobility(read.instances, lidar.name)
    fresh = BlenderScene(scene).mobility(read.instances, lidar.name)
    assert (again.candidates, again.deformable, again.sensor_moves) == \
        (fresh.candidates, fresh.deformable, fresh.sensor_moves)
    assert [read.instances[k].key for k in again.candidates] == ["Car"]
