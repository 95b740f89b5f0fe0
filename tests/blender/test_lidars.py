"""LiDAR objects made and removed by ``blender/lidars.py`` (``rls lidar add|remove``, the
sample scenes' LiDAR): the pose of one facing the region is a study candidate's pose on
the same mount, and removing one takes its outline and preview with it."""

import numpy as np
import pytest

from .conftest import bpy


def test_sample_lidar_has_the_study_candidates_pose(scene):
    from rls_addon.blender.scenes import SAMPLE_LIDARS, add_sample_lidar, build_scene
    from rls_addon.blender.study import BlenderStudyScene
    from rls_addon.core.study.candidates import make_candidates
    from rls_addon.core.study.config import StudyConfig

    build_scene("intersection", scene)
    lidar = add_sample_lidar("intersection", scene)
    mounting = SAMPLE_LIDARS["intersection"]
    assert lidar.name == "LiDAR" and lidar.rls_lidar.preset_id == "hesai_pandar64"
    study = BlenderStudyScene(scene)
    cfg = StudyConfig(device="hesai_pandar64", pitches=(mounting.pitch_deg,))
    polygon = study.region(None)
    (cand,) = [c for c in make_candidates(study.mounts((mounting.mount,)), cfg, polygon)]
    bpy.context.view_layer.update()  # matrix_world follows
    assert np.array(lidar.matrix_world) == pytest.approx(cand.pose, abs=1e-6)
    # its outline is drawn, and it is not a second LiDAR
    assert [c.name for c in lidar.children] == ["LiDAR FOV"]
    from rls_addon.blender.sensor import lidar_objects

    assert [o.name for o in lidar_objects(scene)] == ["LiDAR"]


def test_remove_takes_outline_and_preview(scene):
    from rls_addon.blender.lidars import new_lidar, remove_lidars
    from rls_addon.blender.preview import show_points
    from rls_addon.core.errors import SceneError
    from rls_addon.core.points import empty_points

    a = new_lidar(scene, "A", "hesai_pandar64", (0, 0, 2))
    new_lidar(scene, "B", "hesai_pandar64", (5, 0, 2))
    show_points(scene, a, empty_points(3), "world", np.eye(4))
    assert {"A", "A FOV", "A points", "B", "B FOV"} <= set(bpy.data.objects.keys())
    with pytest.raises(SceneError, match="already has an object named 'A'"):
        new_lidar(scene, "A", "hesai_pandar64")
    with pytest.raises(SceneError, match="no object named 'C'"):
        remove_lidars(scene, ["A", "C"])  # nothing removed: every name checked first
    assert "A" in bpy.data.objects
    assert remove_lidars(scene, ["A", "A"]) == ["A"]
    assert sorted(bpy.data.objects.keys()) == ["B", "B FOV"]


@pytest.mark.parametrize("name", ["t_junction", "intersection", "four_lane"])
def test_every_sample_scene_gets_its_lidar(scene, name):
    from rls_addon.blender.scenes import add_sample_lidar, build_scene

    build_scene(name, scene)
    lidar = add_sample_lidar(name, scene)
    bpy.context.view_layer.update()
    assert lidar.name == "LiDAR" and lidar.matrix_world.translation.z > 6.0


def test_sample_readme_lists_every_scene_make_scenes_writes():
    """sample_scenes/README.md's table names each scene make_scenes.py writes (it once
    listed three of four), and each has its LiDAR."""
    import re
    from pathlib import Path

    from rls_addon.blender.scenes import SAMPLE_LIDARS, SCENES, SUMO_SCENES

    text = (Path(__file__).resolve().parents[2] / "sample_scenes" / "README.md").read_text()
    listed = set(re.findall(r"^\| `(\w+)\.blend` \|", text, re.M))
    assert listed == set(SCENES) | set(SUMO_SCENES)
    assert set(SAMPLE_LIDARS) == set(SCENES) | set(SUMO_SCENES)
