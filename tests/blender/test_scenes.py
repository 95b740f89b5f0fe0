"""The paper's three sample scenes (rls_addon/blender/scenes) and the study's scan path."""

import numpy as np
import pytest

from .conftest import add_lidar, bpy

from rls_addon.blender.labels import object_label
from rls_addon.blender.materials import material_info
from rls_addon.blender.scenes import SCENES, build_scene
from rls_addon.blender.scenes.build import is_mount, mount_position
from rls_addon.core.labels import label_id


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_contents(scene, name):
    info = build_scene(name, scene)
    assert scene.name == name
    lob = bpy.data.objects[info["infralob"]]
    assert lob.get("rls_infralob") and lob.hide_render
    labels = {object_label(o) for o in scene.objects if o.type == "MESH"}
    for want in ("road", "sidewalk", "building", "vehicle", "pedestrian", "cyclist"):
        assert label_id(want) in labels, want
    mounts = [o for o in scene.objects if is_mount(o)]
    assert len(mounts) >= 4 and sorted(o.name for o in mounts) == info["mounts"]
    for o in mounts:
        x, y, z = mount_position(o)
        assert z > 5.0  # on top of a traffic-light or street-light pole
    glossy = [m for m in bpy.data.materials if material_info(m).glossy]
    assert glossy and any(o.active_material in glossy for o in scene.objects if o.type == "MESH")
    # cars drive through: keyframed, in the Vehicles collection (beside the parked ones)
    cars = [bpy.data.objects[n] for n in info["vehicles"] if n not in info["parked"]]
    assert len(cars) >= 3 and info["parked"]
    scene.frame_set(1)
    start = [tuple(c.matrix_world.translation) for c in cars]
    scene.frame_set(30)
    moved = [np.linalg.norm(np.subtract(c.matrix_world.translation, s)) for c, s in zip(cars, start)]
    assert min(moved) > 5.0


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_faces_point_outward(scene, name):
    build_scene(name, scene)
    for o in scene.objects:
        if o.type != "MESH" or len(o.data.polygons) < 6:
            continue
        co = np.array([v.co[:] for v in o.data.vertices])
        c = co.mean(axis=0)
        for p in o.data.polygons:
            assert np.dot(np.array(p.normal[:]), np.array(p.center[:]) - c) > -1e-9, o.name


def test_study_scan_matches_a_lidar_object_scan(scene):
    """The study casts candidates against one prepared structure; a LiDAR object at the
    same pose scanned the ordinary way (vehicles hidden) gives the same points."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.study import run_study
    from rls_addon.core.study.config import StudyConfig

    info = build_scene("intersection", scene)
    cfg = StudyConfig(mounts=("TL NE",), pitches=(10.0,), noise=False, dropout=False,
                      ghosting=False)
    res = run_study(scene, cfg)
    cand = res.candidates[0]
    assert res.structure_builds == 1
    assert sorted(res.hidden_traffic) == info["traffic"]  # vehicles, pedestrians, cyclists
    for name in info["traffic"]:
        bpy.data.objects[name].hide_render = True
    lidar = add_lidar("Check", location=cand.position,
                      rotation=(0.0, np.radians(cand.pitch_deg), np.radians(cand.yaw_deg)))
    lidar.rls_lidar.frame_space = "world"
    from rls_addon.blender.sensor import read_settings

    settings = read_settings(lidar).override(motion="snapshot", ghosting=False)
    result, _ = scan_lidar(lidar, settings=settings)
    xy = res.layout.select([result.points], [1, 2])
    assert len(xy) == cand.n_points
    np.testing.assert_allclose(np.sort(xy, axis=0), np.sort(res.kept_xy(0), axis=0), atol=1e-6)


def test_traffic_is_left_out_unless_kept(scene):
    from rls_addon.blender.study import run_study
    from rls_addon.core.study.config import StudyConfig

    build_scene("t_junction", scene)
    scene.frame_set(30)  # the turning car is inside the region
    base = dict(mounts=("TL NW",), noise=False, dropout=False)
    without = run_study(scene, StudyConfig(**base)).candidates[0]
    with_cars = run_study(scene, StudyConfig(keep_traffic=True, **base)).candidates[0]
    assert with_cars.n_points < without.n_points  # cars shadow the road
