"""RLS's ground truth read back from what a scan run wrote, as ``Boxes``.

Two sources hold every box of a frame, seen or not, as ``ground_truth.ObjectBox.
to_dict`` gives it (``world``: ``centre`` (the box's middle), ``heading_rad`` (yaw of
its length axis, counter-clockwise from world +X), ``rotation``; ``size_lwh_m``;
``label``; ``points``: returns on the object; ``visible_share``; ``instance``):

- an RLS ``kitti`` dataset (``rls dataset --layout kitti``, ``datasets/kitti.py``):
  ``meta/NNNNNN.json`` per frame, its ``objects`` and ``sensor_pose_start``;
- scan sidecars (``rls scan``, ``io/writer.py`` ``CloudWriter``): the JSON beside each
  cloud (``io/sidecar.py``), its ``objects`` (present when ground truth was on),
  ``frame`` (the scene frame), ``sensor`` and ``sensor_pose_start``.

Boxes are taken in the world as written (no frame conversion): score 1, ``points``
the box's point count. Only the classes evaluation scores are kept (vehicle,
pedestrian, cyclist: ``detections.CLASS_IDS``). With each set come the frames read
(a frame without boxes counts) and the sensor's pose per frame at its sweep start,
for distance bins (``GroundTruth.distance``); box centres, for regions, are the
Boxes' first three columns."""

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..output.io.names import sanitize_name
from .detections import CLASS_IDS, Boxes
from .kitti_meta import KittiMeta


@dataclass
class GroundTruth:
    boxes: Boxes            # world boxes, score 1, points = returns on the object
    frames: list            # every frame read, with boxes or without
    sensor_pose: dict       # frame -> (4, 4) sensor -> world at the sweep start
    visible_share: np.ndarray  # (N,) float: share of rays over the box that reach it (NaN: none)
    instance: np.ndarray    # (N,) int64: the object's stable instance id
    sensor: str = ""
    speed: np.ndarray = None  # (N,) float: horizontal speed of the box, m/s (NaN: unknown)

    def __post_init__(self):
        if self.speed is None:
            self.speed = np.full(len(self.boxes), np.nan)

    def sensor_position(self, frame):
        """(3,) world position of the sensor in ``frame`` (at its sweep start)."""
        pose = self.sensor_pose.get(int(frame))
        if pose is None:
            raise InputError(f"frame {int(frame)} is not among the ground truth's frames of "
                             f"{self.sensor or 'the sensor'}")
        return pose[:3, 3]

    def distance(self, boxes=None, horizontal=False):
        """(N,) distance (m) of each box centre (default: the ground truth's) from the
        sensor of its frame; ``horizontal``: in the x-y plane only."""
        b = self.boxes if boxes is None else boxes
        origin = np.array([self.sensor_position(f) for f in b.frame]).reshape(-1, 3)
        d = b.box[:, :3] - origin
        if horizontal:
            d = d[:, :2]
        return np.linalg.norm(d, axis=1)


def _speed(box):
    """Horizontal speed (m/s) of a sidecar box's centre, NaN when it gives none."""
    try:
        v = [float(x) for x in box["world"]["velocity_mps"][:2]]
    except (KeyError, TypeError, ValueError, IndexError):
        return np.nan
    return float(np.hypot(*v)) if len(v) == 2 else np.nan


def _objects_to_rows(objects, where):
    """(boxes (N, 7), labels, points, visible share, instances, speeds) of sidecar
    objects."""
    rows, labels, points, share, inst, speed = [], [], [], [], [], []
    for k, b in enumerate(objects):
        try:
            label = int(b["label"])
            if label not in CLASS_IDS:
                continue
            w = b["world"]
            rows.append([float(v) for v in w["centre"]] + [float(v) for v in b["size_lwh_m"]]
                        + [float(w["heading_rad"])])
            labels.append(label)
            points.append(float(b["points"]))
            vs = b.get("visible_share")
            share.append(np.nan if vs is None else float(vs))
            inst.append(int(b.get("instance", 0)))
            speed.append(_speed(b))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: object {k} is not a ground-truth box "
                             f"({type(exc).__name__}: {exc})") from None
        if len(rows[-1]) != 7:
            raise InputError(f"{where}: object {k} has a centre or size of the wrong length")
    return (np.array(rows, np.float64).reshape(-1, 7), np.array(labels, np.int64),
            np.array(points, np.float64), np.array(share, np.float64),
            np.array(inst, np.int64), np.array(speed, np.float64))


def _pose(info, where):
    try:
        m = np.asarray(info["sensor_pose_start"], np.float64)
    except (KeyError, TypeError, ValueError):
        m = None
    if m is None or m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"{where}: no valid sensor_pose_start (a 4x4 matrix)")
    return m


def _assemble(entries, sensor):
    """GroundTruth of [(frame, objects, pose, where)]."""
    parts, shares, insts, speeds, poses, frames = [], [], [], [], {}, []
    for frame, objects, pose, where in entries:
        if frame in poses:
            raise InputError(f"{where}: frame {frame} of {sensor} is given twice")
        box, label, pts, share, inst, speed = _objects_to_rows(objects, where)
        parts.append(Boxes(np.full(len(box), frame), box, label, 1.0, pts))
        shares.append(share)
        insts.append(inst)
        speeds.append(speed)
        poses[frame] = pose
        frames.append(frame)
    boxes = Boxes.concat(parts).validate(f"ground truth of {sensor}")
    share = np.concatenate(shares) if shares else np.zeros(0)
    inst = np.concatenate(insts).astype(np.int64) if insts else np.zeros(0, np.int64)
    speed = np.concatenate(speeds) if speeds else np.zeros(0)
    return GroundTruth(boxes, sorted(frames), poses, share, inst, sensor, speed)


def ground_truth_from_kitti(dataset):
    """``GroundTruth`` of an RLS ``kitti`` dataset (sensor root or ``KittiMeta``)."""
    meta = dataset if isinstance(dataset, KittiMeta) else KittiMeta.open(dataset)
    entries, sensor = [], meta.root.name
    for frame in meta.frames:
        m = meta.meta(frame)
        where = str(meta.paths[frame])
        if "objects" not in m:
            raise InputError(f"{where}: no 'objects' (ground-truth boxes)")
        sensor = m.get("sensor", sensor)
        entries.append((frame, m["objects"] or [], _pose(m, where), where))
    return _assemble(entries, sensor)


def _sidecar_files(path):
    p = Path(path)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise InputError(f"{p}: no such sidecar file or folder")
    return sorted(p.rglob("*.json"))


def ground_truth_from_sidecars(path, sensor=None):
    """``GroundTruth`` of the scan sidecars in a folder (searched through its
    sub-folders) or of one sidecar file; ``sensor`` picks one when several sensors'
    sidecars are there."""
    found = {}
    for f in _sidecar_files(path):
        try:
            info = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read {f}: {exc}") from None
        if not isinstance(info, dict) or "objects" not in info:
            continue  # not a sidecar with ground truth (instance tables, other JSON)
        frame = info.get("frame")
        if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0:
            raise InputError(f"{f}: 'frame' is {frame!r}, not a scene frame number")
        name = str(info.get("sensor", ""))
        found.setdefault(name, []).append((frame, info["objects"] or [],
                                           _pose(info, str(f)), str(f)))
    if not found:
        raise InputError(f"{path}: no scan sidecar with ground truth (a JSON with 'objects'; "
                         "scan with ground truth on)")
    if sensor is None:
        if len(found) > 1:
            raise InputError(f"{path}: sidecars of several sensors ({', '.join(sorted(found))}); "
                             "choose one (sensor=...)")
        sensor = next(iter(found))
    if sensor not in found:
        raise InputError(f"{path}: no sidecars of sensor {sensor!r} (found "
                         f"{', '.join(sorted(found))})")
    return _assemble(sorted(found[sensor], key=lambda e: e[0]), sensor)


def read_ground_truth(path, sensor=None):
    """``GroundTruth`` of an RLS ``kitti`` dataset (a folder with ``meta/``, or one
    sensor's under it) or of scan sidecars (a folder of them, or one)."""
    p = Path(path)
    if p.is_dir() and ((p / "meta").is_dir() or any((d / "meta").is_dir()
                                                      for d in p.iterdir() if d.is_dir())):
        if sensor is not None and not (p / "meta").is_dir():
            p = p / sanitize_name(sensor)
        return ground_truth_from_kitti(p)
    return ground_truth_from_sidecars(p, sensor)


__all__ = ["GroundTruth", "ground_truth_from_kitti", "ground_truth_from_sidecars",
           "read_ground_truth"]
