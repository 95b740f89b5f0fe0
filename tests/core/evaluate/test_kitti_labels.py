"""Detections as text files in RLS's kitti label layout: RLS's own labels read back
are its ground truth, the writer round-trips, bad files give one clear error."""

import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.ground_truth_files import ground_truth_from_kitti
from rls_addon.core.evaluate.kitti_labels import read_label_files, write_detections

from .builders import kitti_dataset, pose

PITCHED = pose(2.0, -1.0, 6.0, yaw=math.radians(30), pitch=math.radians(15),
               roll=math.radians(3))


def assert_same_boxes(a, b, atol=1e-6):
    """Same boxes (world, to atol; yaw modulo 2 pi), in any order within a frame."""
    assert len(a) == len(b)
    ka, kb = np.lexsort((a.box[:, 0], a.frame)), np.lexsort((b.box[:, 0], b.frame))
    np.testing.assert_array_equal(a.frame[ka], b.frame[kb])
    np.testing.assert_array_equal(a.label[ka], b.label[kb])
    np.testing.assert_allclose(a.box[ka, :6], b.box[kb, :6], rtol=0, atol=atol)
    dyaw = np.angle(np.exp(1j * (a.box[ka, 6] - b.box[kb, 6])))
    np.testing.assert_allclose(dyaw, 0, atol=atol)


@pytest.mark.parametrize("level, moving", [(False, False), (True, False), (True, True)])
def test_rls_labels_read_as_detections_are_its_ground_truth(tmp_path, level, moving):
    root = kitti_dataset(tmp_path / "ds", PITCHED, level=level, moving=moving)
    notices = []
    det, frames = read_label_files(root / "labels", root, notices)
    gt = ground_truth_from_kitti(root)
    seen = gt.boxes.take(gt.boxes.points > 0)  # labels keep boxes with points
    assert frames == [1, 2] and len(seen) == 6
    assert_same_boxes(det, seen)
    assert (det.score == 1).all() and np.isnan(det.points).all()
    assert not notices


def test_moving_sensor_in_its_own_frame_gets_a_notice(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, level=False, moving=True)
    notices = []
    read_label_files(root / "labels", root, notices)
    assert len(notices) == 1 and "--level" in notices[0]


def test_writer_round_trips_world_boxes_with_scores(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1, 2, 3))
    gt = ground_truth_from_kitti(root).boxes
    boxes = gt.take(gt.frame != 3)
    boxes.score = np.linspace(0.1, 0.9, len(boxes))
    paths = write_detections(tmp_path / "det", boxes, root)
    assert [p.name for p in paths] == ["000001.txt", "000002.txt", "000003.txt"]
    assert paths[2].read_text() == ""  # a frame without detections
    back, frames = read_label_files(tmp_path / "det", root)
    assert frames == [1, 2, 3]
    assert_same_boxes(back, boxes)
    np.testing.assert_allclose(np.sort(back.score), np.sort(boxes.score), atol=1e-6)
    line = paths[0].read_text().splitlines()[0].split()
    assert len(line) == 9 and line[7] in ("Vehicle", "Pedestrian", "Cyclist")


def test_known_box_in_level_and_pitched_frames(tmp_path):
    """One hand-placed detection line per label frame lands where computed by hand."""
    for level in (False, True):
        sensor = pose(0.0, 0.0, 5.0, yaw=math.pi / 2, pitch=math.radians(30))
        root = kitti_dataset(tmp_path / f"ds{level}", sensor, level=level, frames=(7,))
        det = tmp_path / f"det{level}"
        det.mkdir()
        c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
        # world box: centre (0, 10, 1) (10 m ahead of the yawed sensor), yaw 180 deg
        # (across the view: the sensor frame's +y is world -x)
        x, z = (10.0, -4.0) if level else (10 * c + 4 * s, 10 * s - 4 * c)
        (det / "000007.txt").write_text(f"{x} 0 {z} 4 2 1.5 {math.pi / 2} Car 0.75\n")
        out, _ = read_label_files(det, root)
        np.testing.assert_allclose(out.box[0, :6], [0.0, 10.0, 1.0, 4.0, 2.0, 1.5], atol=1e-9)
        assert abs(math.cos(out.box[0, 6]) + 1) < 1e-9
        assert out.label[0] == 11 and out.score[0] == 0.75


@pytest.mark.parametrize("line, message", [
    ("1 2 0.5 nan 1.8 1.5 0.1 Vehicle 0.9", r"000001\.txt, line 2: a NaN"),
    ("1 2 0.5 4 -1.8 1.5 0.1 Vehicle 0.9", r"000001\.txt, line 2: sizes dx dy dz must be above"),
    ("1 2 0.5 4 1.8 1.5 0.1 Tram 0.9",
     r"line 2: unknown class 'Tram'.*vehicle, pedestrian, cyclist"),
    ("1 2 0.5 4 1.8 1.5 0.1 Vehicle 1.5", r"line 2: score 1.5 is outside"),
    ("1 2 0.5 4 1.8 1.5 Vehicle", r"line 2: 7 columns; expected 'x y z dx dy dz heading"),
    ("Car 0.00 0 -1.58 587.0 173.3 614.1 200.1 1.65 1.67 3.64 -0.65 1.71 46.70 -1.59 0.9",
     r"line 2: this is KITTI's label_2 format.*calib file"),
    # numbers no detection has: scored before, with an overflow warning from the overlap
    ("1e308 2 0.5 4 1.8 1.5 0.1 Vehicle 0.9",
     r"000001\.txt, line 2: a box centre at 1e\+308 2\.0 0\.5 m, farther than 100000 m"),
    ("1 2 -2e5 4 1.8 1.5 0.1 Vehicle 0.9", r"line 2: a box centre .* farther than 100000 m"),
    ("1 2 0.5 4 1e200 1.5 0.1 Vehicle 0.9", r"line 2: sizes dx dy dz .* at most 1000 m"),
    ("1 2 0.5 4 1.8 1.5 1e30 Vehicle 0.9",
     r"000001\.txt, line 2: heading 1e\+30 rad is not an angle a detector gives"),
])
def test_bad_lines_give_one_clear_error(tmp_path, line, message):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1,))
    det = tmp_path / "det"
    det.mkdir()
    (det / "000001.txt").write_text("1 2 0.5 4 1.8 1.5 0.1 Vehicle 0.9\n" + line + "\n")
    with pytest.raises(InputError, match=message):
        read_label_files(det, root)


def test_bad_folders_give_one_clear_error(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1,))
    det = tmp_path / "det"
    det.mkdir()
    with pytest.raises(InputError, match=r"det: no detection files"):
        read_label_files(det, root)
    (det / "frame_a.txt").write_text("")
    with pytest.raises(InputError, match=r"frame_a\.txt: frame id 'frame_a' is not a frame number"):
        read_label_files(det, root)
    (det / "frame_a.txt").unlink()
    (det / "000009.txt").write_text("")
    with pytest.raises(InputError, match=r"000009\.txt: frame 9 is not in the dataset"):
        read_label_files(det, root)
    with pytest.raises(InputError, match="not an RLS 'kitti' dataset"):
        read_label_files(det, tmp_path / "det")


def test_headings_and_offsets_within_the_limits_are_read_exactly(tmp_path):
    """Just inside the limits: a heading of 999 rad and a box 99 km out are boxes."""
    root = kitti_dataset(tmp_path / "ds", np.eye(4), frames=(1,))
    det = tmp_path / "det"
    det.mkdir()
    (det / "000001.txt").write_text("99000 2 0.5 4 1.8 1.5 999 Vehicle 0.9\n")
    boxes, _ = read_label_files(det, root)
    np.testing.assert_allclose(boxes.box[0, :6], [99000, 2, 0.5, 4, 1.8, 1.5], rtol=0, atol=1e-9)
    assert abs(np.angle(np.exp(1j * (boxes.box[0, 6] - 999.0)))) < 1e-9  # the same heading


def test_boxes_beyond_a_world_are_refused_by_every_reader():
    for row in ([2e7, 0, 0, 4, 2, 1.5, 0], [0, 0, 0, 4, 2e3, 1.5, 0], [0, 0, 0, 4, 2, 1.5, -1e4]):
        with pytest.raises(InputError, match=r"result\.pkl: box 0 of frame 3 is no box of a "
                                             r"road user"):
            Boxes([3], [row], [11], [0.5]).validate("result.pkl")
    Boxes([3], [[9e6, -9e6, 0, 4, 2, 1.5, 3.0]], [11], [0.5]).validate()


def test_datasets_name_their_scene_and_two_scenes_are_refused(tmp_path):
    from rls_addon.core.evaluate.kitti_meta import KittiMeta, one_scene

    a = KittiMeta.open(kitti_dataset(tmp_path / "a", PITCHED, frames=(1,), scene="t_junction"))
    b = KittiMeta.open(kitti_dataset(tmp_path / "b", PITCHED, frames=(1,), scene="intersection"))
    same = KittiMeta.open(kitti_dataset(tmp_path / "c", PITCHED, frames=(1,), scene="t_junction"))
    assert (a.scene, b.scene) == ("t_junction", "intersection")  # from the frames' meta
    (b.root / "dataset.json").write_text('{"scene": "intersection"}')
    assert b.scene == "intersection"  # from dataset.json
    one_scene([("--truth A", a), ("--dataset C", same)])
    with pytest.raises(InputError, match="--truth A is a dataset of scene 't_junction' and "
                                         "--dataset B of scene 'intersection'"):
        one_scene([("--truth A", a), ("--dataset C", same), ("--dataset B", b)])


def test_writer_refuses_invalid_boxes(tmp_path):
    root = kitti_dataset(tmp_path / "ds", PITCHED, frames=(1,))
    bad = Boxes([1], [[0, 0, 0, 1, np.nan, 1, 0]], [11], [0.5])
    with pytest.raises(InputError, match="NaN"):
        write_detections(tmp_path / "det", bad, root)
