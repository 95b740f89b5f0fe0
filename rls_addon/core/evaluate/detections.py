"""Boxes, as every stage of evaluation hands them on.

A box is seven numbers in RLS's world frame (metres, radians): the centre ``x y z`` (the
box's middle, not its floor), ``length`` along its heading, ``width``, ``height``, and
``yaw``, counter-clockwise from world +X about +Z. This is OpenPCDet's ``boxes_lidar``
order (``x y z dx dy dz heading``) in the world instead of a sensor's frame, and what
``ground_truth.ObjectBox`` gives as ``centre``, ``size`` and ``heading``.

``Boxes`` holds a set of boxes with their frame, class (an RLS label id: vehicle 11,
pedestrian 12, cyclist 18) and score (1.0 for ground truth); ``points`` counts a
ground-truth box's returns (NaN for detections)."""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..labels import DEFAULT_LABELS, OBJECT_CLASSES, NAME_TO_ID

# The classes evaluation scores, as RLS label ids.
CLASS_IDS = tuple(NAME_TO_ID[name] for name in OBJECT_CLASSES)
BOX_COLUMNS = ("x", "y", "z", "length", "width", "height", "yaw")
# What a box in the world can be (every reader's boxes pass ``validate``): a world within
# 1e7 m of its origin (UTM's northings are below that), a road user shorter than 1 km,
# a yaw that is an angle. Beyond them a number is a writer's bug; at 1e154 the overlap's
# products overflow (a warning, then a wrong IoU).
MAX_WORLD_M = 1e7
MAX_SIZE_M = 1e3
MAX_YAW_RAD = 1e3


def class_id(name):
    """The label id of an evaluated class given by name, in any case ('Car' and 'car' are
    vehicles, as KITTI and OpenPCDet name them); one error listing the known names."""
    key = str(name).strip().lower()
    key = {"car": "vehicle", "van": "vehicle", "truck": "vehicle", "bus": "vehicle",
           "person": "pedestrian", "bicycle": "cyclist"}.get(key, key)
    found = NAME_TO_ID.get(key)
    if found not in CLASS_IDS:
        known = ", ".join(DEFAULT_LABELS[i] for i in CLASS_IDS)
        raise InputError(f"unknown class '{name}': RLS evaluates {known} "
                         "(also accepted: Car, Van, Truck, Bus, Person, Bicycle)")
    return found


@dataclass
class Boxes:
    frame: np.ndarray   # (N,) int64: the scene frame each box belongs to
    box: np.ndarray     # (N, 7) float64: x y z length width height yaw (world frame)
    label: np.ndarray   # (N,) int64: RLS label id
    score: np.ndarray   # (N,) float64
    points: np.ndarray = None  # (N,) float64: a ground-truth box's returns; NaN otherwise

    def __post_init__(self):
        self.box = np.asarray(self.box, np.float64).reshape(-1, 7)
        n = len(self.box)
        self.frame = np.broadcast_to(np.asarray(self.frame, np.int64), (n,)).copy()
        self.label = np.broadcast_to(np.asarray(self.label, np.int64), (n,)).copy()
        self.score = np.broadcast_to(np.asarray(self.score, np.float64), (n,)).copy()
        points = np.nan if self.points is None else self.points
        self.points = np.broadcast_to(np.asarray(points, np.float64), (n,)).copy()

    def __len__(self):
        return len(self.box)

    def validate(self, source="boxes"):
        """Refuse what no box can be: NaN or infinite numbers, sizes not above zero,
        numbers beyond ``MAX_WORLD_M``, ``MAX_SIZE_M`` and ``MAX_YAW_RAD``, scores outside
        [0, 1] or NaN, classes RLS does not evaluate."""
        bad = ~np.isfinite(self.box).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{source}: box {i} of frame {self.frame[i]} has a NaN or "
                             f"infinite value: {self.box[i].tolist()}")
        bad = (self.box[:, 3:6] <= 0).any(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{source}: box {i} of frame {self.frame[i]} has a size that "
                             f"is not positive: {self.box[i, 3:6].tolist()}")
        bad = (np.abs(self.box[:, :3]) > MAX_WORLD_M).any(axis=1) \
            | (self.box[:, 3:6] > MAX_SIZE_M).any(axis=1) | (np.abs(self.box[:, 6]) > MAX_YAW_RAD)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{source}: box {i} of frame {self.frame[i]} is no box of a road "
                             f"user: {self.box[i].tolist()} (x y z within {MAX_WORLD_M:g} m "
                             f"of the world's origin, sizes at most {MAX_SIZE_M:g} m, yaw at "
                             f"most {MAX_YAW_RAD:g} rad either way)")
        bad = ~((self.score >= 0) & (self.score <= 1))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{source}: box {i} of frame {self.frame[i]} has score "
                             f"{self.score[i]!r}; scores must lie in [0, 1]")
        bad = ~np.isin(self.label, CLASS_IDS)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            known = ", ".join(DEFAULT_LABELS[c] for c in CLASS_IDS)
            raise InputError(f"{source}: box {i} has label {self.label[i]}; RLS "
                             f"evaluates {known}")
        return self

    def take(self, index):
        """The boxes at ``index`` (a mask or indices), as a new ``Boxes``."""
        return Boxes(self.frame[index], self.box[index], self.label[index],
                     self.score[index], self.points[index])

    @classmethod
    def empty(cls):
        return cls(np.zeros(0, np.int64), np.zeros((0, 7)), np.zeros(0, np.int64),
                   np.zeros(0))

    @classmethod
    def concat(cls, parts):
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        return cls(np.concatenate([p.frame for p in parts]),
                   np.concatenate([p.box for p in parts]),
                   np.concatenate([p.label for p in parts]),
                   np.concatenate([p.score for p in parts]),
                   np.concatenate([p.points for p in parts]))
