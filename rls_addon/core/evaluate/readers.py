"""Detections from a file or folder, whatever wrote them: one entry for evaluation.

Formats (``FORMATS``), and what tells them apart when none is given:

``kitti``      a folder of ``NNNNNN.txt``, one per frame, lines ``x y z dx dy dz
               heading Class score`` in the dataset's label frame (``kitti_labels``)
``openpcdet``  OpenPCDet's ``result.pkl`` (``tools/test.py``), a ``.pkl`` file or a
               folder holding ``result.pkl`` (``openpcdet``)
``opencood``   OpenCOOD's ``npy`` folder (``inference.py --save_npy``): files
               ``NNNN_pred.npy`` (``opencood``)

``dataset`` is what the detector ran on, whose poses place the boxes in the world:
an RLS ``kitti`` dataset's sensor folder (``kitti``, ``openpcdet``) or the OPV2V test
root (``opencood``). Every set is validated (``Boxes.validate``): NaN or infinite
numbers, sizes not above zero, scores outside [0, 1], unknown classes are refused
with one ``InputError`` naming the file."""

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from .detections import Boxes
from .kitti_labels import read_label_files
from .opencood import PRED, read_opencood_npy
from .openpcdet import read_result_pkl

FORMATS = ("kitti", "openpcdet", "opencood")


@dataclass
class DetectionFiles:
    boxes: Boxes            # world boxes
    frames: list            # every frame the source covers (with boxes or without)
    format: str
    notices: list = field(default_factory=list)  # what the user should be told


def detect_format(path):
    """The format of ``path`` (see the module docstring); ``InputError`` otherwise."""
    p = Path(path)
    if p.is_file():
        if p.suffix.lower() == ".pkl":
            return "openpcdet"
        raise InputError(f"{p}: not a detection file RLS reads (OpenPCDet's result.pkl); "
                         "detections in text are a folder of NNNNNN.txt, one per frame")
    if not p.is_dir():
        raise InputError(f"{p}: no such file or folder of detections")
    names = [q.name for q in p.iterdir()]
    if any(PRED.match(n) for n in names):
        return "opencood"
    if any(n.endswith(".txt") for n in names):
        return "kitti"
    if "result.pkl" in names:
        return "openpcdet"
    raise InputError(f"{p}: no detections found (NNNNNN.txt files, OpenPCDet's result.pkl "
                     "or OpenCOOD's NNNN_pred.npy); the folder is empty of them")


def read_detection_files(path, fmt=None, dataset=None, scenario=None):
    """``DetectionFiles`` of ``path`` in format ``fmt`` (None: detected) made on
    ``dataset``; ``scenario``: for OpenCOOD predictions spanning several scenarios."""
    fmt = detect_format(path) if fmt is None else str(fmt).lower()
    if fmt not in FORMATS:
        raise InputError(f"unknown detection format {fmt!r}: use one of {', '.join(FORMATS)}")
    if dataset is None:
        what = "the OPV2V test root (the folder of scenario folders)" if fmt == "opencood" \
            else "the RLS kitti dataset's sensor folder (with meta/)"
        raise InputError(f"{path}: reading {fmt} detections needs the dataset they were made "
                         f"on, whose poses place them in the world: give {what}")
    notices = []
    p = Path(path)
    if fmt == "kitti":
        boxes, frames = read_label_files(p, dataset, notices)
    elif fmt == "openpcdet":
        if p.is_dir():
            p = p / "result.pkl"
        boxes, frames = read_result_pkl(p, dataset, notices)
    else:
        boxes, frames = read_opencood_npy(p, dataset, scenario, notices)
    return DetectionFiles(boxes, frames, fmt, notices)


def read_detections(path, fmt=None, dataset=None, scenario=None):
    """World ``Boxes`` of the detections at ``path`` (see ``read_detection_files``)."""
    return read_detection_files(path, fmt, dataset, scenario).boxes


__all__ = ["DetectionFiles", "FORMATS", "detect_format", "read_detection_files",
           "read_detections"]
