"""RLS's roadside detector run over datasets that ``rls dataset --layout kitti`` wrote:
one sensor root per still LiDAR (``points/NNNNNN.npy`` or ``.bin``, ``meta/NNNNNN.json``),
early fusion when several are given. Each frame's points are taken back to their
sensor's own frame (the detector reads the sensor's range image): from the dataset's
frame (the sensor frame, or with ``--level`` a gravity-aligned frame) to the world
(``frame_to_world``), then to the sensor at its sweep start (``sensor_pose_start``).
The background is learned from the dataset's frames (or the ones named); the detections
are ``Boxes`` in the world, written as detection files of the first dataset
(``kitti_labels.write_detections``: its label frame, with a score)."""

import time
from pathlib import Path

import numpy as np

from ..device.presets import get_preset
from ..errors import InputError, RLSError
from .detections import Boxes
from .detector import RoadsideDetector, detect_frame, learn_sensors
from .kitti_meta import KittiMeta

DEFAULT_NOISE_SIGMA_M = 0.02  # when the dataset's meta does not give the device's


def frame_points(meta, frame):
    """(N, 3) float64 points of ``frame`` in its sensor's frame at the sweep start."""
    root = meta.root
    npy, raw = root / "points" / f"{frame:06d}.npy", root / "points" / f"{frame:06d}.bin"
    try:
        if npy.exists():
            arr = np.load(npy, allow_pickle=False)
        elif raw.exists():
            arr = np.fromfile(raw, dtype=np.float32).reshape(-1, 4)
        else:
            raise InputError(f"{root}: frame {frame} has meta but no points/{frame:06d}.npy "
                             "or .bin")
    except (OSError, ValueError) as exc:
        raise InputError(f"{root}: cannot read the points of frame {frame}: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise InputError(f"{root}: points of frame {frame} are not (N, 4) x y z intensity")
    xyz = np.asarray(arr[:, :3], np.float64)
    to_sensor = np.linalg.inv(meta.sensor_pose(frame)) @ meta.frame_to_world(frame)
    return xyz @ to_sensor[:3, :3].T + to_sensor[:3, 3]


def noise_sigma_of(meta):
    """The range noise (m) of the device the dataset's meta names (its preset's), else
    ``DEFAULT_NOISE_SIGMA_M``."""
    device = meta.meta(meta.frames[0]).get("device")
    pid = device.get("id") if isinstance(device, dict) else None
    try:
        return float(get_preset(pid).range.noise_sigma_m) if pid else DEFAULT_NOISE_SIGMA_M
    except RLSError:  # a user preset not installed here
        return DEFAULT_NOISE_SIGMA_M


def detect_datasets(roots, background_frames=None, noise_sigma=None, progress=None,
                    detector=None):
    """Detect every frame the datasets ``roots`` share. Returns (Boxes in the world, the
    frames, {"learn_s", "detect_s" (per frame), "sensors"}). ``progress(i, n, frame)``
    after each frame."""
    metas = [KittiMeta.open(r) for r in roots]
    names = [m.root.name for m in metas]
    if len(set(names)) != len(names):
        raise InputError(f"the datasets name one sensor twice: {', '.join(names)}")
    frames = sorted(set.intersection(*(set(m.frames) for m in metas)))
    if not frames:
        raise InputError("the datasets share no frame: " + ", ".join(str(m.root) for m in metas))
    learn = frames if background_frames is None else sorted(int(f) for f in background_frames)
    unknown = [f for f in learn if f not in frames]
    if unknown:
        raise InputError(f"background frames {unknown[:5]} are not among the datasets' "
                         f"frames ({frames[0]}-{frames[-1]})")
    if detector is None:
        sigma = max(noise_sigma_of(m) for m in metas) if noise_sigma is None else noise_sigma
        detector = RoadsideDetector(noise_sigma=float(sigma))
    t0 = time.perf_counter()
    learned = learn_sensors(detector,
                            {n: [frame_points(m, f) for f in learn] for n, m in zip(names, metas)},
                            {n: m.sensor_pose(learn[0]) for n, m in zip(names, metas)})
    learn_s = time.perf_counter() - t0
    found, seconds = [], []
    for i, f in enumerate(frames):
        points = {n: frame_points(m, f) for n, m in zip(names, metas)}
        t = time.perf_counter()
        found.append(detect_frame(detector, learned, points,
                                  {n: m.sensor_pose(f) for n, m in zip(names, metas)}, frame=f))
        seconds.append(time.perf_counter() - t)
        if progress is not None:
            progress(i + 1, len(frames), f)
    return Boxes.concat(found), frames, {"learn_s": learn_s, "detect_s": seconds,
                                         "sensors": names}


def write_dataset_detections(folder, boxes, roots, frames, overwrite=False):
    """Write ``boxes`` as detection files of the first dataset of ``roots``."""
    from .kitti_labels import write_detections

    return write_detections(Path(folder), boxes, roots[0], frames=frames, overwrite=overwrite)
