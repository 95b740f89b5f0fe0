"""The frames and poses of a dataset RLS wrote in its ``kitti`` layout (OpenPCDet's
custom dataset; ``datasets/kitti.py``), as evaluation reads them back.

A sensor root holds ``meta/NNNNNN.json`` per frame (NNNNNN: the scene frame number,
``datasets.common.frame_id``), written last, so a frame with meta is complete. Each
meta has ``frame_to_world`` (4x4: the frame of that frame's points and labels ->
world), ``label_frame`` (``sensor``: the sensor's own frame, ``frame_to_world`` its pose
at the sweep start; ``level``: the gravity-aligned frame at the sensor at the sweep
start, ``datasets.common.level_frame``),
``sensor_pose_start``, ``sensor_poses`` (knots, for a sensor that moved during its
sweep) and ``objects``: every ground-truth box (``ground_truth.ObjectBox.to_dict``,
seen or not) with ``frame_box``, the box as its label line gives it.

A root given may be the sensor root (it has ``meta/``) or a dataset output folder
with exactly one sensor root in it."""

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .frame_ids import frame_number


def sensor_root(path):
    """The sensor root (the folder holding ``meta/``) at or under ``path``."""
    p = Path(path)
    if (p / "meta").is_dir():
        return p
    if not p.is_dir():
        raise InputError(f"{p}: no such dataset folder (an RLS 'kitti' dataset: the sensor "
                         "folder holding points/, labels/ and meta/)")
    found = sorted(d for d in p.iterdir() if (d / "meta").is_dir())
    if len(found) == 1:
        return found[0]
    if not found:
        raise InputError(f"{p}: not an RLS 'kitti' dataset (no meta/ folder in it or in a "
                         "sensor folder under it; written by 'rls dataset --layout kitti')")
    raise InputError(f"{p}: holds several sensors' datasets ({', '.join(d.name for d in found)}); "
                     "give the folder of the sensor the detections were made on")


@dataclass
class KittiMeta:
    """The meta files of one sensor root: ``paths`` {frame: meta path}."""
    root: Path
    paths: dict = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def open(cls, path):
        root = sensor_root(path)
        paths = {}
        for p in sorted((root / "meta").glob("*.json")):
            paths[frame_number(p.stem, str(p))] = p
        if not paths:
            raise InputError(f"{root / 'meta'}: no meta files (NNNNNN.json): the dataset "
                             "holds no complete frame")
        return cls(root, paths)

    @property
    def frames(self):
        return sorted(self.paths)

    def meta(self, frame, where=None):
        """The meta dict of ``frame``; ``InputError`` (naming ``where``, the file that
        asked) when the dataset has no such frame or its meta is unreadable."""
        if frame in self._cache:
            return self._cache[frame]
        path = self.paths.get(int(frame))
        if path is None:
            raise InputError(f"{where or self.root}: frame {frame} is not in the dataset "
                             f"{self.root} (no meta/{int(frame):06d}.json); were the "
                             "detections made on another dataset?")
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read {path}: {exc}") from None
        if not isinstance(data, dict):
            raise InputError(f"{path}: not an RLS meta file (a JSON object)")
        self._cache[frame] = data
        return data

    def frame_to_world(self, frame, where=None):
        """The 4x4 of ``frame``'s label frame -> world."""
        return _matrix(self.meta(frame, where), "frame_to_world", self.paths[int(frame)])

    def sensor_pose(self, frame, where=None):
        """The sensor's 4x4 pose (sensor -> world) at the sweep start of ``frame``."""
        return _matrix(self.meta(frame, where), "sensor_pose_start", self.paths[int(frame)])

    @property
    def scene(self):
        """The scene the dataset was written from: its ``dataset.json``'s ``scene``,
        else its first frame's meta's; None when neither names one."""
        try:
            info = json.loads((self.root / "dataset.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            info = None
        scene = info.get("scene") if isinstance(info, dict) else None
        if scene is None:
            scene = self.meta(self.frames[0]).get("scene")
        return None if scene is None else str(scene)

    def label_frame(self, frame):
        return self.meta(frame).get("label_frame", "sensor")

    def moving_sensor_notice(self, frames):
        """A notice when sensor-frame boxes of a sensor that moved during its sweep are
        placed with its sweep-start pose (see ``kitti_labels``), else None."""
        moved = [f for f in frames if self.label_frame(f) == "sensor"
                 and self.meta(f).get("sensor_poses")]
        if not moved:
            return None
        return (f"{self.root.name}: the sensor moved during {len(moved)} of its sweeps and its "
                "boxes are in its own (moving) frame; detections are placed in the world "
                "with its pose at the sweep start, off by as far as it travelled before "
                "it scanned each object (write the dataset with --level for exact places)")


def one_scene(datasets):
    """Refuse datasets of different scenes: ``datasets`` is [(what the user gave, e.g.
    "--truth PATH", KittiMeta)]; ``InputError`` naming the first two that differ. Boxes
    detected on one scene's points and scored against another's ground truth would
    give AP 0 without a word."""
    named = [(what, meta.scene) for what, meta in datasets if meta.scene is not None]
    for what, scene in named[1:]:
        if scene != named[0][1]:
            raise InputError(f"{named[0][0]} is a dataset of scene {named[0][1]!r} and {what} "
                             f"of scene {scene!r}: detections are scored against the ground "
                             "truth of the scene they were made on; give datasets of one scene")


def _matrix(meta, key, path):
    try:
        m = np.asarray(meta[key], np.float64)
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{path}: no valid {key} (a 4x4 matrix)") from None
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"{path}: {key} is not a finite 4x4 matrix")
    return m


__all__ = ["KittiMeta", "one_scene", "sensor_root"]
