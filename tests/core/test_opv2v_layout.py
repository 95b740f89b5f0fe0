"""OPV2V's YAML as OpenCOOD reads it (DerrickXuNu/OpenCOOD, main of 2024-08-16):
``opencood/data_utils/post_processor/base_postprocessor.py`` ``generate_object_center``
merges every agent's ``params['vehicles']`` and ``box_utils.project_world_objects``
turns each entry into a ground-truth box of the one class OPV2V has; no entry's
category is read."""

import numpy as np
import yaml

from rls_addon.core.output.datasets.opv2v import Opv2vWriter, agents_for

from .evaluate.builders import OBJECTS, VEHICLE, info, object_boxes, points, pose

EGO = pose(5.0, 2.0, 1.9, yaw=0.3)
RSU = pose(0.0, -8.0, 6.0, yaw=0.2, pitch=0.17)


def test_vehicles_lists_vehicles_only(tmp_path):
    """A pedestrian or cyclist among 'vehicles' is a car to OpenCOOD: the walker and the
    bike of the builders' scene were listed there (and trained on as vehicles)."""
    carriers = {"roof": "car"}
    writer = Opv2vWriter(tmp_path, "scene", agents_for(["roof", "pole"], carriers), carriers)
    for sensor, p in (("roof", EGO), ("pole", RSU)):
        writer.write(sensor, None, 3, points(), info(p, object_boxes(p)))
    names = {100 + k: (name, label) for k, (name, label, *_) in enumerate(OBJECTS)}
    for agent in writer.scenario.iterdir():
        body = yaml.safe_load((agent / "000003.yaml").read_text())
        carrier = body["rls"]["carrier"]
        want = {i for i, (n, label) in names.items() if label == VEHICLE and n != carrier}
        assert set(body["vehicles"]) == want
        assert all(v["category"] == "vehicle" for v in body["vehicles"].values())
        others = body["rls"]["other_objects"]
        assert sorted(v["rls_object"] for v in others.values()) == ["bike", "walker"]
        np.testing.assert_allclose(others[101]["extent"], [0.3, 0.3, 0.9])
    assert sum(n.startswith("OPV2V lists vehicles only") for n in writer.notices) == 1


def test_a_moving_lidars_points_are_where_its_lidar_pose_puts_them(tmp_path):
    """OpenCOOD maps every point of a .pcd by the one pose of its YAML
    (``basedataset.reform_param``: ``x1_to_x2(lidar_pose, ego lidar_pose)``; CARLA's LiDAR
    has no motion within a tick). A LiDAR driving 1.5 m during its sweep wrote its points
    each in its frame at its own time with ``lidar_pose`` at the sweep start: OpenCOOD put
    them up to 1.5 m from where they were, and from their boxes."""
    from rls_addon.core.output.datasets.carla import carla_matrix
    from rls_addon.core.output.io import pcd
    from rls_addon.core.scene.motion import poses_at

    start = pose(5.0, 2.0, 1.9, yaw=0.3)
    end = start.copy()
    end[:3, 3] += (1.5, 0.0, 0.0)
    knots = {"times_s": [0.0, 0.1], "matrices": [start.tolist(), end.tolist()]}
    world = np.array([[12.0, 3.0, 0.5], [4.0, 9.0, 1.0], [-3.0, 1.0, 0.2], [6.0, -6.0, 0.8]])
    pts = points(len(world))
    pts["time"] = [0.0, 0.03, 0.06, 0.099]
    at = poses_at(knots["times_s"], knots["matrices"], pts["time"])
    local = np.einsum("nji,nj->ni", at[:, :3, :3], world - at[:, :3, 3])  # R^T (w - t)
    pts["x"], pts["y"], pts["z"] = local[:, 0], local[:, 1], local[:, 2]
    writer = Opv2vWriter(tmp_path, "scene", agents_for(["roof"], {}))
    writer.write("roof", None, 1, pts, info(start, [], knots))
    agent, = writer.scenario.iterdir()
    body = yaml.safe_load((agent / "000001.yaml").read_text())
    got = pcd.decode((agent / "000001.pcd").read_bytes())
    xyz = np.stack([got["x"], got["y"], got["z"]], 1).astype(np.float64)
    m = carla_matrix(body["lidar_pose"])  # opencood/utils/transformation_utils.x_to_world
    placed = xyz @ m[:3, :3].T + m[:3, 3]
    placed[:, 1] *= -1.0  # CARLA's y is Blender's -y
    np.testing.assert_allclose(placed, world, atol=1e-4)
    # a still LiDAR's points are written as they are
    still = Opv2vWriter(tmp_path / "still", "scene", agents_for(["roof"], {}))
    still.write("roof", None, 1, pts, info(start, []))
    agent, = still.scenario.iterdir()
    got = pcd.decode((agent / "000001.pcd").read_bytes())
    np.testing.assert_array_equal(got["x"], pts["x"].astype(np.float32))
    np.testing.assert_array_equal(got["y"], -pts["y"].astype(np.float32))


def test_a_kitti_lidar_on_a_car_does_not_label_its_car(tmp_path):
    """A dataset audit found a roof LiDAR's KITTI labels holding a box around the car
    that carries it in every frame (KITTI-style datasets never label their ego: a free
    target at the sensor). The carrier stays in meta/, named there; a road-side
    LiDAR's labels keep every vehicle."""
    import json

    from rls_addon.core.output.datasets.kitti import KittiWriter

    writer = KittiWriter(tmp_path, "scene", carriers={"roof": "car"})
    for sensor, p in (("roof", EGO), ("pole", RSU)):
        writer.write(sensor, None, 3, points(), info(p, object_boxes(p)))
    writer.flush()
    counts = {}
    for sensor in ("roof", "pole"):
        meta = json.loads((tmp_path / sensor / "meta" / "000003.json").read_text())
        seen = [b for b in meta["objects"] if b["points"] >= 1]
        lines = (tmp_path / sensor / "labels" / "000003.txt").read_text().splitlines()
        counts[sensor] = (len(seen), len(lines), meta.get("carrier"))
        assert "car" in [b["object"] for b in meta["objects"]]
    assert counts["roof"] == (counts["pole"][0], counts["pole"][0] - 1, "car")
    assert counts["pole"][1:] == (counts["pole"][0], None)
