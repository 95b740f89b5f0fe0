"""read_detections: the format found from the path, the dataset asked for, every set
validated, bad input one clear error."""

import math
import os
import pickle

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.ground_truth_files import read_ground_truth
from rls_addon.core.evaluate.kitti_labels import write_detections
from rls_addon.core.evaluate.opencood import opv2v_samples
from rls_addon.core.evaluate.readers import (detect_format, read_detection_files,
                                             read_detections)

from .builders import kitti_dataset, opv2v_dataset, pose
from .test_kitti_labels import assert_same_boxes
from .test_opencood import EGO, RSU, write_predictions
from .test_openpcdet import result_from_labels

SENSOR = pose(1.0, 2.0, 5.0, yaw=2.0, pitch=math.radians(8))


def test_each_format_is_found_and_read(tmp_path):
    root = kitti_dataset(tmp_path / "ds", SENSOR, frames=(1, 2))
    gt = read_ground_truth(root).boxes
    seen = gt.take(gt.points > 0)
    write_detections(tmp_path / "txt", seen, root)
    (tmp_path / "pcdet").mkdir()
    (tmp_path / "pcdet" / "result.pkl").write_bytes(pickle.dumps(result_from_labels(root, [1, 2])))
    for path, fmt in ((tmp_path / "txt", "kitti"), (tmp_path / "pcdet", "openpcdet"),
                      (tmp_path / "pcdet" / "result.pkl", "openpcdet")):
        assert detect_format(path) == fmt
        got = read_detection_files(path, dataset=root)
        assert got.format == fmt and got.frames == [1, 2] and not got.notices
        assert_same_boxes(got.boxes, seen)
    opv2v = tmp_path / "opv2v"
    opv2v_dataset(opv2v, EGO, RSU, frames=(3,))
    write_predictions(tmp_path / "npy", opv2v_samples(opv2v))
    assert detect_format(tmp_path / "npy") == "opencood"
    assert len(read_detections(tmp_path / "npy", dataset=opv2v)) == 2  # its vehicles


def test_missing_or_unknown_things_give_one_clear_error(tmp_path):
    root = kitti_dataset(tmp_path / "ds", SENSOR, frames=(1,))
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty.*no detections found"):
        read_detections(tmp_path / "empty", dataset=root)
    with pytest.raises(InputError, match="no detection files"):
        read_detections(tmp_path / "empty", fmt="kitti", dataset=root)
    with pytest.raises(InputError, match="unknown detection format 'yolo'"):
        read_detections(tmp_path / "empty", fmt="yolo", dataset=root)
    with pytest.raises(InputError, match="no such file or folder"):
        read_detections(tmp_path / "nowhere", dataset=root)
    (tmp_path / "det").mkdir()
    (tmp_path / "det" / "000001.txt").write_text("")
    with pytest.raises(InputError, match="needs the dataset they were made on"):
        read_detections(tmp_path / "det")
    assert len(read_detections(tmp_path / "det", dataset=root)) == 0


class _Touch:
    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (os.system, (f"touch '{self.path}'",))


def test_malicious_result_pkl_is_refused(tmp_path):
    root = kitti_dataset(tmp_path / "ds", SENSOR, frames=(1,))
    marker = tmp_path / "marker"
    data = result_from_labels(root, [1])
    data[0]["metadata"] = _Touch(marker)
    (tmp_path / "result.pkl").write_bytes(pickle.dumps(data))
    with pytest.raises(InputError, match=r"result\.pkl: refused to load: it names .*system"):
        read_detections(tmp_path / "result.pkl", dataset=root)
    assert not marker.exists()


def test_scores_are_validated(tmp_path):
    root = kitti_dataset(tmp_path / "ds", SENSOR, frames=(1,))
    data = result_from_labels(root, [1])
    data[0]["score"] = np.array([0.5, 7.0, 0.1])
    (tmp_path / "result.pkl").write_bytes(pickle.dumps(data))
    with pytest.raises(InputError, match=r"result\.pkl: box 1 of frame 1 has score 7\.0"):
        read_detections(tmp_path / "result.pkl", dataset=root)
