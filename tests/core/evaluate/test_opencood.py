"""OpenCOOD's saved predictions on an OPV2V dataset RLS wrote: ground-truth corners
made the way OpenCOOD makes them read back as RLS's world boxes."""

import math

import numpy as np
import pytest
import yaml

from rls_addon.core.output.datasets.carla import carla_matrix
from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.corners import boxes_to_corners, corners_to_boxes
from rls_addon.core.evaluate.opencood import opv2v_samples, read_opencood_npy

from .builders import opv2v_dataset, pose

EGO = pose(5.0, 2.0, 1.9, yaw=0.3, pitch=math.radians(2))
RSU = pose(0.0, -8.0, 6.0, yaw=0.2, pitch=math.radians(10))


def create_bbx(extent):
    """opencood/utils/box_utils.py create_bbx: corners from half sizes."""
    e0, e1, e2 = extent
    return np.array([[e0, -e1, -e2], [e0, e1, -e2], [-e0, e1, -e2], [-e0, -e1, -e2],
                     [e0, -e1, e2], [e0, e1, e2], [-e0, e1, e2], [-e0, -e1, e2]])


def opencood_gt_corners(yaml_path):
    """(N, 8, 3) corners of a YAML's vehicles in its LiDAR frame, as OpenCOOD's
    project_world_objects computes them (x1_to_x2 of location + center and angle)."""
    body = yaml.safe_load(yaml_path.read_text())
    to_lidar = np.linalg.inv(carla_matrix(body["lidar_pose"]))
    out = []
    for v in body["vehicles"].values():
        loc = np.add(v["location"], v["center"])
        m = to_lidar @ carla_matrix([*loc, *v["angle"]])
        c = create_bbx(v["extent"])
        out.append(c @ m[:3, :3].T + m[:3, 3])
    return np.array(out)


def write_predictions(npy, samples, dtype=np.float64):
    npy.mkdir(exist_ok=True)
    for i, (_, ego, stamp) in enumerate(samples):
        np.save(npy / f"{i:04d}_pred.npy", opencood_gt_corners(ego / f"{stamp}.yaml").astype(dtype))
        np.save(npy / f"{i:04d}_gt.npy_test", np.zeros((0, 8, 3)))


def test_ground_truth_corners_read_back_as_world_boxes(tmp_path):
    root = tmp_path / "test"
    scenario, truth = opv2v_dataset(root, EGO, RSU, frames=(3, 4))
    samples = opv2v_samples(root)
    ego = samples[0][1].name
    assert [(s.name, e.name, t) for s, e, t in samples] == \
        [(scenario.name, ego, "000003"), (scenario.name, ego, "000004")]
    assert int(samples[0][1].name) > 0  # the road-side unit (negative id) is never ego
    write_predictions(tmp_path / "npy", samples)
    det, frames = read_opencood_npy(tmp_path / "npy", root)
    assert frames == [3, 4] and (det.label == 11).all() and (det.score == 1).all()
    for f in frames:
        got = det.box[det.frame == f]
        want = truth[f]
        order = np.argsort(got[:, 0]), np.argsort(want[:, 0])
        np.testing.assert_allclose(got[order[0], :6], want[order[1], :6], atol=1e-6)
        dyaw = np.angle(np.exp(1j * (got[order[0], 6] - want[order[1], 6])))
        np.testing.assert_allclose(dyaw, 0, atol=1e-6)


def test_float32_corners_as_torch_saves_them(tmp_path):
    root = tmp_path / "test"
    _, truth = opv2v_dataset(root, EGO, RSU, frames=(3,))
    write_predictions(tmp_path / "npy", opv2v_samples(root), np.float32)
    det, _ = read_opencood_npy(tmp_path / "npy", root)
    np.testing.assert_allclose(np.sort(det.box[:, 0]), np.sort(truth[3][:, 0]), atol=2e-5)


def test_known_box_in_a_known_ego_pose(tmp_path):
    """CARLA pose [10, -5, 2, roll 0, yaw 90, pitch 0] is Blender (10, 5, 2) turned
    -90 deg; a box at (4, 1, 0) along the ego's x in CARLA's axes is at (4, -1, 0) in
    Blender's, so at (9, 1, 2) in the world, yaw -90 deg."""
    ego = tmp_path / "test" / "scene" / "5"
    ego.mkdir(parents=True)
    (ego / "000007.yaml").write_text(yaml.safe_dump({"lidar_pose": [10, -5, 2, 0, 90, 0]}))
    npy = tmp_path / "npy"
    npy.mkdir()
    np.save(npy / "0000_pred.npy", boxes_to_corners([[4.0, 1.0, 0.0, 4.0, 2.0, 1.5, 0.0]]))
    det, frames = read_opencood_npy(npy, tmp_path / "test")
    assert frames == [7]
    np.testing.assert_allclose(det.box, [[9.0, 1.0, 2.0, 4.0, 2.0, 1.5, -math.pi / 2]],
                               atol=1e-9)
    notices = []
    read_opencood_npy(npy, tmp_path / "test", notices=notices)
    assert not notices
    (ego / "000007.yaml").write_text(yaml.safe_dump({"lidar_pose": [10, -5, 2, 0, 90, 0],
                                                     "rls": {"sensor_moves": True}}))
    read_opencood_npy(npy, tmp_path / "test", notices=notices)
    assert len(notices) == 1 and "moved during 1 of its sweeps" in notices[0]
    # RLS now writes a moving LiDAR's points in the frame of its lidar_pose: exact
    (ego / "000007.yaml").write_text(yaml.safe_dump({
        "lidar_pose": [10, -5, 2, 0, 90, 0],
        "rls": {"sensor_moves": True, "settings": {"points_frame": "lidar_pose"}}}))
    notices = []
    read_opencood_npy(npy, tmp_path / "test", notices=notices)
    assert not notices


def test_sample_order_spans_scenarios(tmp_path):
    root = tmp_path / "test"
    opv2v_dataset(root, EGO, RSU, frames=(3, 4), scene="a_scene")
    _, truth_b = opv2v_dataset(root, EGO, RSU, frames=(1, 2), scene="b_scene")
    samples = opv2v_samples(root)
    assert [(s.name, t) for s, _, t in samples] == [
        ("a_scene", "000003"), ("a_scene", "000004"), ("b_scene", "000001"), ("b_scene", "000002")]
    write_predictions(tmp_path / "npy", samples)
    with pytest.raises(InputError, match="span scenarios a_scene, b_scene"):
        read_opencood_npy(tmp_path / "npy", root)
    det, frames = read_opencood_npy(tmp_path / "npy", root, scenario="b_scene")
    assert frames == [1, 2]
    np.testing.assert_allclose(np.sort(det.box[det.frame == 2, 0]), np.sort(truth_b[2][:, 0]),
                               atol=1e-6)
    with pytest.raises(InputError, match="this is one scenario's folder"):
        read_opencood_npy(tmp_path / "npy", root / "a_scene")


def test_bad_predictions_give_one_clear_error(tmp_path):
    root = tmp_path / "test"
    opv2v_dataset(root, EGO, RSU, frames=(3,))
    npy = tmp_path / "npy"
    write_predictions(npy, opv2v_samples(root))
    corners = np.load(npy / "0000_pred.npy")
    corners[1, 5] += (0.2, 0.0, 0.0)
    np.save(npy / "0000_pred.npy", corners)
    with pytest.raises(InputError, match=r"0000_pred\.npy: the 8 corners of box 1 are not a box"):
        read_opencood_npy(npy, root)
    np.save(npy / "0000_pred.npy", np.zeros((2, 4, 3)))
    with pytest.raises(InputError, match=r"shape \(2, 4, 3\)"):
        read_opencood_npy(npy, root)
    (npy / "0000_pred.npy").unlink()
    np.save(npy / "0001_pred.npy", corners)
    with pytest.raises(InputError, match="sample 1 but .* has 1 samples"):
        read_opencood_npy(npy, root)
    (npy / "0001_pred.npy").unlink()
    np.save(npy / "abcd_pred.npy", corners)
    with pytest.raises(InputError, match="frame id 'abcd' is not a frame number"):
        read_opencood_npy(npy, root)
    (npy / "abcd_pred.npy").unlink()
    with pytest.raises(InputError, match="no OpenCOOD predictions"):
        read_opencood_npy(npy, root)


def test_corner_fit_refuses_flat_and_skewed_sets():
    good = boxes_to_corners([[1, 2, 3, 4, 2, 1.5, 0.7]])
    np.testing.assert_allclose(corners_to_boxes(good), [[1, 2, 3, 4, 2, 1.5, 0.7]], atol=1e-12)
    skew = good.copy()
    skew[0, 4:] += (0.3, 0.0, 0.0)  # the top slid over the bottom: parallel but not square
    with pytest.raises(InputError, match="not a box"):
        corners_to_boxes(skew)
    flat = good.copy()
    flat[0, 4:, 2] = flat[0, :4, 2]
    with pytest.raises(InputError, match="size of zero"):
        corners_to_boxes(flat)
