"""OpenPCDet's result.pkl on an RLS kitti dataset: its ground truth written as
OpenPCDet writes predictions reads back as that ground truth."""

import math
import pickle

import numpy as np
import pytest

from rls_addon.core.output.datasets.kitti import read_labels
from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.ground_truth_files import ground_truth_from_kitti
from rls_addon.core.evaluate.openpcdet import read_result_pkl

from .builders import kitti_dataset, pose
from .test_kitti_labels import assert_same_boxes

PITCHED = pose(-3.0, 4.0, 7.0, yaw=-1.1, pitch=math.radians(20))
CLASSES = ["Vehicle", "Pedestrian", "Cyclist"]


def result_from_labels(root, frames, dtype=np.float64):
    """det_annos as DatasetTemplate.generate_prediction_dicts builds them from the
    label files (the detector found the ground truth)."""
    ids = np.stack([np.array(f"{f:06d}") for f in frames])  # collate_batch: np.stack
    out = []
    for k, f in enumerate(frames):
        boxes, names = read_labels(root / "labels" / f"{f:06d}.txt")
        labels = np.array([CLASSES.index(n) + 1 for n in names], np.int64)
        out.append({"name": np.array(CLASSES)[labels - 1] if len(labels) else np.zeros(0),
                    "score": np.linspace(0.9, 0.5, len(boxes)).astype(np.float32),
                    "boxes_lidar": boxes.astype(dtype).reshape(-1, 7),
                    "pred_labels": labels, "frame_id": ids[k]})
    return out


@pytest.mark.parametrize("level", [False, True])
def test_ground_truth_as_result_pkl_reads_back(tmp_path, level):
    root = kitti_dataset(tmp_path / "ds", PITCHED, level=level, frames=(1, 2))
    path = tmp_path / "result.pkl"
    path.write_bytes(pickle.dumps(result_from_labels(root, [1, 2])))
    det, frames = read_result_pkl(path, root)
    gt = ground_truth_from_kitti(root).boxes
    assert frames == [1, 2]
    assert_same_boxes(det, gt.take(gt.points > 0))
    assert det.score.max() == pytest.approx(0.9)


def test_float32_boxes_and_empty_frames(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1, 2))
    data = result_from_labels(root, [1, 2], np.float32)
    data[1].update(name=np.zeros(0), score=np.zeros(0), boxes_lidar=np.zeros((0, 7)),
                   pred_labels=np.zeros(0))  # get_template_prediction of no boxes
    path = tmp_path / "result.pkl"
    path.write_bytes(pickle.dumps(data, protocol=4))
    det, frames = read_result_pkl(path, root)
    gt = ground_truth_from_kitti(root).boxes
    assert frames == [1, 2] and set(det.frame) == {1}
    assert_same_boxes(det, gt.take((gt.points > 0) & (gt.frame == 1)), atol=2e-5)


@pytest.mark.parametrize("change, message", [
    ({"frame_id": np.str_("frame_a")}, r"entry 0: frame id 'frame_a' is not a frame number"),
    ({"name": np.array(["Vehicle", "Tram", "Cyclist"])}, r"box 1: unknown class 'Tram'"),
    ({"boxes_lidar": np.full((3, 7), np.nan)}, r"result\.pkl: box 0 of frame 1 has a NaN"),
    ({"boxes_lidar": np.tile([[1, 2, 0, 4, -1.8, 1.5, 0]], (3, 1))},
     r"result\.pkl: box 0 of frame 1 has a size that is not positive"),
    ({"frame_id": np.str_("000042")}, r"frame 42 is not in the dataset"),
])
def test_bad_entries_give_one_clear_error(tmp_path, change, message):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1,))
    data = result_from_labels(root, [1])
    data[0].update(change)
    path = tmp_path / "result.pkl"
    path.write_bytes(pickle.dumps(data))
    with pytest.raises(InputError, match=message):
        read_result_pkl(path, root)


def test_not_a_result_list(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1,))
    path = tmp_path / "result.pkl"
    for data, message in (({"a": 1}, "holds a dict"), ([], "holds no frames"),
                          ([{"frame_id": "000001"}], "no name, score, boxes_lidar")):
        path.write_bytes(pickle.dumps(data))
        with pytest.raises(InputError, match=message):
            read_result_pkl(path, root)
