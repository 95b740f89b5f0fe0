"""RLS's ground truth read back from a kitti dataset's meta files and from scan
sidecars: the world boxes the scan produced, with points, frames and sensor poses."""

import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.ground_truth_files import (ground_truth_from_sidecars,
                                                        read_ground_truth)
from rls_addon.core.output.io.sidecar import write_sidecar

from .builders import OBJECTS, info, kitti_dataset, object_boxes, pose

SENSOR = pose(2.0, -1.0, 6.0, yaw=0.5, pitch=math.radians(12))


def expected(frame):
    return np.array([[c[0] + frame, c[1], c[2], *s, y] for _, _, c, s, y, _ in OBJECTS])


def test_kitti_meta_ground_truth(tmp_path):
    root = kitti_dataset(tmp_path / "ds", SENSOR, level=False, frames=(4, 5))
    for path in (root, tmp_path / "ds"):  # the sensor root or the output folder
        gt = read_ground_truth(path)
        assert gt.frames == [4, 5] and gt.sensor == "lidar"
        np.testing.assert_allclose(gt.boxes.box[gt.boxes.frame == 5], expected(5), atol=1e-12)
        np.testing.assert_array_equal(gt.boxes.label[:4], [11, 12, 18, 11])
        np.testing.assert_array_equal(gt.boxes.points[:4], [120, 30, 12, 0])
        assert (gt.boxes.score == 1).all()
        np.testing.assert_array_equal(gt.visible_share[:4], [0.5, 0.5, 0.5, np.nan])
        np.testing.assert_allclose(gt.sensor_position(4), [2.0, -1.0, 6.0])
        d = gt.distance()
        assert abs(d[0] - np.linalg.norm(expected(4)[0, :3] - [2, -1, 6])) < 1e-12
        assert abs(gt.distance(horizontal=True)[0] - math.hypot(16 - 2, 3 + 1)) < 1e-12


def _sidecars(folder, sensor, p, frames, objects=OBJECTS):
    for f in frames:
        body = dict(info(p, object_boxes(p, (float(f), 0, 0), objects)), frame=f,
                    sensor=sensor, points=5)
        write_sidecar(folder / f"{sensor}_{f:06d}.pcd", body)


def test_sidecar_ground_truth(tmp_path):
    _sidecars(tmp_path, "front", SENSOR, (1, 2))
    _sidecars(tmp_path, "rear", pose(yaw=math.pi), (1, 2))
    (tmp_path / "scene_instances.json").write_text('{"instances": {}}')
    with pytest.raises(InputError, match=r"several sensors \(front, rear\)"):
        ground_truth_from_sidecars(tmp_path)
    gt = read_ground_truth(tmp_path, sensor="rear")
    assert gt.frames == [1, 2] and gt.sensor == "rear" and len(gt.boxes) == 8
    np.testing.assert_allclose(gt.boxes.box[gt.boxes.frame == 2], expected(2), atol=1e-12)
    np.testing.assert_allclose(gt.sensor_pose[1], pose(yaw=math.pi))
    one = read_ground_truth(tmp_path / "front_000001.json")
    assert one.frames == [1] and len(one.boxes) == 4


def test_classes_not_evaluated_are_left_out(tmp_path):
    pole = [("pole", 6, (5.0, 5.0, 2.0), (0.3, 0.3, 4.0), 0.0, 40)]
    _sidecars(tmp_path, "front", SENSOR, (1,), OBJECTS + pole)
    gt = read_ground_truth(tmp_path)
    assert len(gt.boxes) == 4 and 6 not in gt.boxes.label


def test_missing_ground_truth_is_one_clear_error(tmp_path):
    write_sidecar(tmp_path / "a.pcd", {"frame": 1, "sensor": "x"})
    with pytest.raises(InputError, match="no scan sidecar with ground truth"):
        read_ground_truth(tmp_path)
    write_sidecar(tmp_path / "b.pcd", {"frame": "sensor", "sensor": "x", "objects": []})
    with pytest.raises(InputError, match=r"b\.json: 'frame' is 'sensor'"):
        read_ground_truth(tmp_path)


def test_each_box_carries_its_horizontal_speed(tmp_path):
    """What scoring splits standing from moving boxes by: the box centre's world
    velocity in the meta, horizontal."""
    gt = read_ground_truth(kitti_dataset(tmp_path, pose(z=5.0)))
    assert gt.speed.shape == (len(gt.boxes),) and (gt.speed == 0.0).all()
