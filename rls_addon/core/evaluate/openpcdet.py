"""OpenPCDet's ``result.pkl`` (``tools/test.py``) on RLS's ``kitti`` dataset.

Checked at the source (open-mmlab/OpenPCDet, master of 2024-04-17):
``tools/eval_utils/eval_utils.py`` ``eval_one_epoch`` pickles ``det_annos``, the list
that ``dataset.generate_prediction_dicts`` returns per batch, as
``<output>/eval/.../result.pkl``. The custom dataset (``pcdet/datasets/custom/
custom_dataset.py``) keeps ``DatasetTemplate.generate_prediction_dicts``
(``pcdet/datasets/dataset.py``): one dict per frame with

    name         (N,) str     class names, ``class_names[pred_labels - 1]``
    score        (N,) float32
    boxes_lidar  (N, 7) float32 ``x y z dx dy dz heading`` (N, 9 with speeds)
    pred_labels  (N,) int     1-based index into the config's CLASS_NAMES
    frame_id     str          the sample id from ImageSets (numpy str after collation)
    metadata     (optional)   passed through from the batch

``boxes_lidar`` is in the frame of the points the detector read: the dataset's
``points/NNNNNN.npy``, i.e. the frame of its labels (meta ``label_frame``: the sensor's
frame, or the level frame with ``--level``). ``frame_id`` is the ImageSets id, which
RLS's ``kitti`` layout makes the frame number in six digits. Boxes go to the world with
the meta's ``frame_to_world`` (``box_frames.to_world``), as ``kitti_labels`` does.

The file is loaded by ``safe_pickle`` (numpy arrays and plain data only)."""

import numpy as np

from ..errors import InputError
from .box_frames import to_world
from .detections import Boxes, class_id
from .frame_ids import frame_number
from .kitti_meta import KittiMeta
from .safe_pickle import load_pickle

KEYS = ("frame_id", "name", "score", "boxes_lidar")


def _array(entry, key, where):
    try:
        return np.asarray(entry[key])
    except Exception as exc:  # noqa: BLE001 - anything odd in a foreign file
        raise InputError(f"{where}: '{key}' is not an array ({exc})") from None


def _entry(entry, where):
    """(frame, boxes (N, 7) in the frame, label ids, scores) of one result dict."""
    if not isinstance(entry, dict):
        raise InputError(f"{where}: not a dict (OpenPCDet's result.pkl is a list of "
                         f"dicts with {', '.join(KEYS)})")
    missing = [k for k in KEYS if k not in entry]
    if missing:
        raise InputError(f"{where}: no {', '.join(missing)} (OpenPCDet's result.pkl entries "
                         f"have {', '.join(KEYS)})")
    fid = entry["frame_id"]
    if isinstance(fid, np.ndarray) and fid.size == 1:
        fid = fid.reshape(()).item()
    frame = frame_number(fid, where)
    where = f"{where} (frame_id {fid!s})"
    boxes = _array(entry, "boxes_lidar", where)
    names = _array(entry, "name", where).reshape(-1)
    scores = _array(entry, "score", where).reshape(-1)
    if boxes.size == 0 and len(names) == 0:
        return frame, np.zeros((0, 7)), np.zeros(0, np.int64), np.zeros(0)
    if boxes.ndim != 2 or boxes.shape[1] < 7:
        raise InputError(f"{where}: boxes_lidar has shape {boxes.shape}; expected (N, 7) "
                         "x y z dx dy dz heading (or N, 9 with speeds)")
    n = len(boxes)
    if len(names) != n or len(scores) != n:
        raise InputError(f"{where}: {n} boxes but {len(names)} names and {len(scores)} scores")
    try:
        box = boxes[:, :7].astype(np.float64)
        score = scores.astype(np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: boxes_lidar and score must be numbers") from None
    labels = []
    for i, name in enumerate(names):
        try:
            labels.append(class_id(name))
        except InputError as exc:
            raise InputError(f"{where}, box {i}: {exc}") from None
    return frame, box, np.array(labels, np.int64), score


def read_result_pkl(path, dataset, notices=None):
    """(Boxes in the world, frames read) of OpenPCDet's ``result.pkl`` made on the
    points of ``dataset`` (an RLS ``kitti`` sensor root, or its ``KittiMeta``)."""
    meta = dataset if isinstance(dataset, KittiMeta) else KittiMeta.open(dataset)
    data = load_pickle(path)
    if not isinstance(data, (list, tuple)):
        raise InputError(f"{path}: holds a {type(data).__name__}; OpenPCDet's result.pkl is a "
                         "list of per-frame dicts")
    if not data:
        raise InputError(f"{path}: holds no frames (an empty list)")
    parts, frames = [], []
    for k, entry in enumerate(data):
        where = f"{path}, entry {k}"
        frame, box, label, score = _entry(entry, where)
        if frame in frames:
            raise InputError(f"{where}: frame {frame} appears twice in the file")
        frames.append(frame)
        world = to_world(box, meta.frame_to_world(frame, where))
        parts.append(Boxes(np.full(len(box), frame), world, label, score))
    note = meta.moving_sensor_notice(frames)
    if note and notices is not None:
        notices.append(note)
    return Boxes.concat(parts).validate(str(path)), sorted(frames)


__all__ = ["KEYS", "read_result_pkl"]
