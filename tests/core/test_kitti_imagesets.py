"""The kitti layout's ImageSets (``KittiWriter.finish``): every frame listed there can
be read by OpenPCDet's custom dataset, so a frame whose label file holds no box is left
out of train.txt and val.txt (said, and listed in dataset.json), its files kept."""

import json
from types import SimpleNamespace

import numpy as np

from rls_addon.core.output.datasets.common import Split
from rls_addon.core.output.datasets.kitti import KittiWriter

from .evaluate.builders import info, object_boxes, points, pose

SENSOR = pose(0.0, 0.0, 2.0)


def _run():
    """What ``finish`` reads of a run: its sensors' names, classes and device."""
    output = SimpleNamespace(object_classes=["vehicle", "pedestrian", "cyclist"])
    job = SimpleNamespace(name="lidar", settings=SimpleNamespace(output=output),
                          preset=SimpleNamespace(id="small8"))
    return SimpleNamespace(sensors=[job])


def _dataset(root, empty_frames, frames=range(1, 9), split=None, min_points=1):
    writer = KittiWriter(root, "scene", split=split or Split(0.25, 0), min_points=min_points)
    for f in frames:
        boxes = [] if f in empty_frames else object_boxes(SENSOR, shift=(float(f), 0.0, 0.0))
        writer.write("lidar", None, f, points(), info(SENSOR, boxes))
    writer.finish(_run())
    return writer, writer.sensor_root("lidar")


def _listed(root):
    return [(root / "ImageSets" / f"{part}.txt").read_text().split() for part in ("train", "val")]


def _as_openpcdet_reads(label_file):
    """A label file read as OpenPCDet's custom dataset reads it (``get_label``: each
    line split on spaces, all but the last as float32; then ``get_infos`` keeps
    ``[:, :7]``), which raises IndexError on a file without lines."""
    rows = [line.strip().split(" ")[:-1] for line in label_file.read_text().splitlines()]
    return np.array(rows, dtype=np.float32)[:, :7]


def test_frames_without_boxes_are_left_out_of_the_splits_and_named(tmp_path):
    writer, root = _dataset(tmp_path / "ds", empty_frames={2, 5, 6})
    train, val = _listed(root)
    listed = train + val
    assert sorted(listed) == ["000001", "000003", "000004", "000007", "000008"]
    assert not set(train) & set(val)
    for fid in listed:  # what OpenPCDet's create_custom_infos does to each listed frame
        assert _as_openpcdet_reads(root / "labels" / f"{fid}.txt").shape[1] == 7
    meta = json.loads((root / "dataset.json").read_text())
    assert meta["frames_without_labels"] == ["000002", "000005", "000006"]
    assert meta["frames"] == 8 and meta["val_frames"] == len(val)
    # their files are kept: points, an empty label file, the meta with its boxes (none)
    for fid in ("000002", "000005", "000006"):
        assert (root / "points" / f"{fid}.npy").is_file()
        assert (root / "labels" / f"{fid}.txt").read_text() == ""
        assert (root / "meta" / f"{fid}.json").is_file()
    said = [n for n in writer.notices if "no box in their label file" in n]
    assert len(said) == 1 and "3 of lidar's 8 frames" in said[0]
    assert "000002, 000005, 000006" in said[0]


def test_the_split_is_drawn_over_every_frame_so_a_frame_keeps_its_side(tmp_path):
    """A frame is on the same side (train or val) whether or not other frames have boxes."""
    _, full = _dataset(tmp_path / "a", empty_frames=set())
    _, holed = _dataset(tmp_path / "b", empty_frames={1, 4})
    (train_full, val_full), (train, val) = _listed(full), _listed(holed)
    assert train == [i for i in train_full if i not in ("000001", "000004")]
    assert val == [i for i in val_full if i not in ("000001", "000004")]
    assert json.loads((full / "dataset.json").read_text())["frames_without_labels"] == []


def test_boxes_below_min_points_leave_a_frame_unlabelled_too(tmp_path):
    """Every box of a frame kept out of its labels by --min-points: the label file is
    empty, as with no object at all."""
    writer, root = _dataset(tmp_path / "ds", empty_frames=set(), frames=(1, 2),
                            min_points=10_000)
    assert _listed(root) == [[], []]
    assert json.loads((root / "dataset.json").read_text())["frames_without_labels"] == [
        "000001", "000002"]
    assert any("2 of lidar's 2 frames" in n for n in writer.notices)
