"""Detections as text files in the layout of RLS's ``kitti`` labels, with a score.

A folder holds one file per frame, ``NNNNNN.txt`` (the scene frame number in six
digits, as the dataset's ``labels/`` and ``meta/`` name it; an empty file: a frame
without detections), one box a line, columns separated by spaces:

    x y z dx dy dz heading Class score

The first eight are exactly a line of the dataset's ``labels/NNNNNN.txt``: OpenPCDet's
custom-dataset order (``pcdet/datasets/custom/custom_dataset.py``, ``get_label``:
``x y z dx dy dz heading_angle category_name``; the box centre, its length along the
heading, width, height, heading in radians counter-clockwise from x), the class named
as the dataset names it (Vehicle, Pedestrian, Cyclist; any case, and KITTI's Car, Van,
Truck, Person, ... as ``detections.class_id`` lists). ``score`` (0..1) is appended; a
line without it (8 columns, a label file) has score 1.

Frame: the frame of the dataset's points and labels, which its meta states
(``label_frame``): the sensor's own frame, or with ``--level`` the gravity-aligned frame
at the sensor. Boxes go to the world through the meta's ``frame_to_world``
(``box_frames.to_world``; exact for level frames and still sensors; a sensor that moved
during its sweep without ``--level`` is placed with its sweep-start pose, and a notice
says so).

KITTI's own ``label_2`` rows (``type truncated occluded alpha bbox(4) h w l x y z ry
[score]``, the KITTI object devkit's readme; what OpenPCDet's KITTI dataset writes with
``--save_to_file``) are refused: they are in a camera's rectified frame, which only a
calibration file (``Tr_velo_to_cam``, ``R0_rect``) relates to the LiDAR, and RLS's
datasets have neither camera nor calibration.

``write_detections`` writes this format (RLS's own detector does), turning world boxes
into each frame's label frame with the same meta poses."""

import math
from pathlib import Path

import numpy as np

from ..output.datasets.kitti import class_name
from ..errors import InputError
from ..output.io.atomic import atomic_write_bytes, ensure_directory
from ..labels import label_name
from .box_frames import to_frame, to_world
from .detections import Boxes, class_id
from .frame_ids import frame_number
from .kitti_meta import KittiMeta

COLUMNS = "x y z dx dy dz heading Class score"
# What a detection in a label frame (centred on its sensor) can be: no LiDAR sees a box
# 100 km away or 1 km long, and a heading is an angle (float64 keeps 1e3 rad to 1e-13).
# Beyond them a number is a writer's bug, and at 1e154 the overlap's products overflow.
MAX_OFFSET_M = 1e5
MAX_SIZE_M = 1e3
MAX_HEADING_RAD = 1e3


def _is_number(token):
    try:
        float(token)
    except ValueError:
        return False
    return True


def parse_lines(text, where):
    """(boxes (N, 7) in the file's frame, label ids (N,), scores (N,)) of a detection
    file's text; ``InputError`` naming ``where`` and the line."""
    boxes, labels, scores = [], [], []
    for n, line in enumerate(text.splitlines(), 1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        at = f"{where}, line {n}"
        if not _is_number(tokens[0]) and len(tokens) in (15, 16):
            raise InputError(
                f"{at}: this is KITTI's label_2 format (type truncated occluded alpha bbox "
                "h w l x y z ry score), in a camera frame that only a calib file relates "
                "to the LiDAR; RLS datasets have no camera: write LiDAR-frame boxes as "
                f"'{COLUMNS}' (OpenPCDet's boxes_lidar order)")
        if len(tokens) not in (8, 9):
            raise InputError(f"{at}: {len(tokens)} columns; expected '{COLUMNS}' (8 columns "
                             "without the score)")
        try:
            values = [float(t) for t in tokens[:7]]
            score = float(tokens[8]) if len(tokens) == 9 else 1.0
        except ValueError:
            raise InputError(f"{at}: not a number where '{COLUMNS}' has one: "
                             f"{line.strip()!r}") from None
        if not all(math.isfinite(v) for v in values + [score]):
            raise InputError(f"{at}: a NaN or infinite value: {line.strip()!r}")
        if min(values[3:6]) <= 0:
            raise InputError(f"{at}: sizes dx dy dz must be above zero, got "
                             f"{values[3]} {values[4]} {values[5]}")
        if max(abs(v) for v in values[:3]) > MAX_OFFSET_M:
            raise InputError(f"{at}: a box centre at {values[0]!r} {values[1]!r} {values[2]!r} "
                             f"m, farther than {MAX_OFFSET_M:g} m from the sensor: not a "
                             "detection a LiDAR can make")
        if max(values[3:6]) > MAX_SIZE_M:
            raise InputError(f"{at}: sizes dx dy dz {values[3]!r} {values[4]!r} {values[5]!r} "
                             f"m; a box of a road user is at most {MAX_SIZE_M:g} m")
        if abs(values[6]) > MAX_HEADING_RAD:
            raise InputError(f"{at}: heading {values[6]!r} rad is not an angle a detector "
                             f"gives (at most {MAX_HEADING_RAD:g} rad either way)")
        if not 0.0 <= score <= 1.0:
            raise InputError(f"{at}: score {score} is outside [0, 1]")
        try:
            labels.append(class_id(tokens[7]))
        except InputError as exc:
            raise InputError(f"{at}: {exc}") from None
        boxes.append(values)
        scores.append(score)
    return (np.array(boxes, np.float64).reshape(-1, 7), np.array(labels, np.int64),
            np.array(scores, np.float64))


def detection_files(folder):
    """{frame: path} of a folder's ``NNNNNN.txt`` files; ``InputError`` for an empty
    folder or a file whose name is not a frame number."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder of detection files")
    files = sorted(folder.glob("*.txt"))
    if not files:
        raise InputError(f"{folder}: no detection files (NNNNNN.txt, one per frame, lines "
                         f"'{COLUMNS}')")
    out = {}
    for p in files:
        out[frame_number(p.stem, str(p))] = p
    return out


def read_label_files(folder, dataset, notices=None):
    """(Boxes in the world, frames read) of a folder of detection files made on the
    points of ``dataset`` (an RLS ``kitti`` sensor root, or its ``KittiMeta``).
    ``notices``: a list that gets what the caller should tell the user."""
    meta = dataset if isinstance(dataset, KittiMeta) else KittiMeta.open(dataset)
    files = detection_files(folder)
    parts = []
    for frame, path in files.items():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read {path}: {exc}") from None
        box, label, score = parse_lines(text, str(path))
        world = to_world(box, meta.frame_to_world(frame, str(path)))
        parts.append(Boxes(np.full(len(box), frame), world, label, score))
    note = meta.moving_sensor_notice(files)
    if note and notices is not None:
        notices.append(note)
    return Boxes.concat(parts).validate(str(folder)), sorted(files)


def format_lines(boxes, labels, scores=None):
    """The text of a detection file: (N, 7) boxes in the label frame, label ids, scores
    (None: a label file's 8 columns)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    lines = []
    for i, row in enumerate(b):
        line = " ".join(f"{v:.6f}" for v in row) + f" {class_name(label_name(int(labels[i])))}"
        if scores is not None:
            line += f" {float(scores[i]):.6f}"
        lines.append(line + "\n")
    return "".join(lines)


def write_label_file(path, boxes, labels, scores, overwrite=False):
    """Write one frame's detections (boxes in its label frame) to ``path``."""
    atomic_write_bytes(path, format_lines(boxes, labels, scores).encode("utf-8"),
                       overwrite=overwrite)
    return Path(path)


def write_detections(folder, boxes, dataset, frames=None, overwrite=False):
    """Write world ``Boxes`` as detection files of ``dataset`` (an RLS ``kitti`` sensor
    root or its ``KittiMeta``): one ``NNNNNN.txt`` per frame in ``frames`` (default: the
    dataset's frames and the boxes'; a frame without boxes gets an empty file), each box
    in that frame's label frame. Returns the paths written."""
    meta = dataset if isinstance(dataset, KittiMeta) else KittiMeta.open(dataset)
    boxes.validate("detections to write")
    frames = sorted(set(meta.frames) | set(int(f) for f in boxes.frame)) if frames is None \
        else sorted(int(f) for f in frames)
    missing = sorted(set(int(f) for f in boxes.frame) - set(frames))
    if missing:
        raise InputError(f"detections of frames {missing[:5]} are not among the frames to "
                         "write")
    ensure_directory(folder)
    out = []
    for frame in frames:
        sel = boxes.frame == frame
        local = to_frame(boxes.box[sel], meta.frame_to_world(frame, "detections to write"))
        out.append(write_label_file(Path(folder) / f"{frame:06d}.txt", local,
                                    boxes.label[sel], boxes.score[sel], overwrite))
    return out


__all__ = ["COLUMNS", "detection_files", "format_lines", "parse_lines", "read_label_files",
           "write_detections", "write_label_file"]
