"""RLS's roadside detector run over datasets that ``rls dataset --layout kitti`` wrote:
one sensor root per still LiDAR (``points/NNNNNN.npy`` or ``.bin``, ``meta/NNNNNN.json``),
early fusion when several are given. Each frame's points are taken back to their
sensor's own frame (the detector reads the sensor's range image): from the dataset's
frame (the sensor frame, or with ``--level`` a gravity-aligned frame) to the world
(``frame_to_world``), then to the sensor at its sweep start (``sensor_pose_start``).
The background is learned by default from the sweeps of the scene with every road user
hidden that ``rls dataset`` stores under each still sensor's ``background/`` (the
background a deployed unit has), or from the dataset's frames (``background="frames"``;
all of them or the ones named). The detector is any that meets the detector protocol
(``detector.protocol``; default RLS's roadside detector with the device's range noise).
The detections are ``Boxes`` in the world, written as detection files of the first
dataset (``kitti_labels.write_detections``: its label frame, with a score) with
``detector.json`` beside them: the detector and the background it learned."""

import time
from pathlib import Path

import numpy as np

from ..device.presets import get_preset
from ..choices import BACKGROUNDS
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


def dataset_types(meta):
    """The scene's types of road users that ``rls dataset`` wrote in the dataset's
    ``dataset.json`` (``class_types``) as ``priors.scene_types`` gives them, or None
    (a dataset without them: the detector's built-in priors)."""
    import json

    from ..labels import label_id

    try:
        about = json.loads((meta.root / "dataset.json").read_text(encoding="utf-8"))
        rows = about.get("class_types") or {}
        return {label_id(name): tuple((*map(float, r["size"]), int(r["objects"]))
                                      for r in kinds)
                for name, kinds in rows.items()} or None
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RLSError):
        return None


def background_meta(meta):
    """``KittiMeta`` of the background sweeps stored with the dataset ``meta``; one
    ``InputError`` saying what to do when there are none."""
    folder = meta.root / "background"
    if not (folder / "meta").is_dir():
        raise InputError(
            f"{meta.root}: no background sweeps (background/meta/): the dataset was written "
            "with --background-sweeps 0, for a LiDAR that may move, or by an RLS before "
            "them; write it again with 'rls dataset', or pass --background frames to learn "
            "the background from its frames")
    return KittiMeta.open(folder)


def _background(metas, names, background, background_frames, frames):
    """({sensor: sweeps}, {sensor: pose}, JSON-ready description) of the background to
    learn."""
    BACKGROUNDS.check(background)
    if background == "empty":
        if background_frames is not None:
            raise InputError("background frames name frames to learn the background from: "
                             "they go with --background frames, not with the empty scene's "
                             "sweeps")
        stored = [background_meta(m) for m in metas]
        sweeps = {n: [frame_points(b, k) for k in b.frames] for n, b in zip(names, stored)}
        poses = {n: b.sensor_pose(b.frames[0]) for n, b in zip(names, stored)}
        first = stored[0].meta(stored[0].frames[0])
        return sweeps, poses, {
            "kind": "empty", "label": BACKGROUNDS.label("empty"),
            "sweeps": {n: len(b.frames) for n, b in zip(names, stored)},
            "scene_frame": first.get("scene_frame"),
            "hidden_labels": first.get("hidden_labels"),
            "what": "each sensor's sweeps of the scene with every road user hidden, stored "
                    "with the dataset (background/)"}
    learn = frames if background_frames is None else sorted(int(f) for f in background_frames)
    unknown = [f for f in learn if f not in frames]
    if unknown:
        raise InputError(f"background frames {unknown[:5]} are not among the datasets' "
                         f"frames ({frames[0]}-{frames[-1]})")
    sweeps = {n: [frame_points(m, f) for f in learn] for n, m in zip(names, metas)}
    poses = {n: m.sensor_pose(learn[0]) for n, m in zip(names, metas)}
    return sweeps, poses, {"kind": "frames", "label": BACKGROUNDS.label("frames"),
                           "frames": learn,
                           "what": "learned from the dataset's frames, traffic and all"}


def detect_datasets(roots, background="empty", background_frames=None, noise_sigma=None,
                    progress=None, detector=None):
    """Detect every frame the datasets ``roots`` share, the background learned as
    ``background`` says ('empty': the stored sweeps of the scene without road users;
    'frames': ``background_frames`` or every frame). Returns (Boxes in the world, the
    frames, {"learn_s", "detect_s" (per frame), "sensors", "background" (what was
    learned), "detector" (its name)}). ``progress(i, n, frame)`` after each frame."""
    metas = [KittiMeta.open(r) for r in roots]
    names = [m.root.name for m in metas]
    if len(set(names)) != len(names):
        raise InputError(f"the datasets name one sensor twice: {', '.join(names)}")
    frames = sorted(set.intersection(*(set(m.frames) for m in metas)))
    if not frames:
        raise InputError("the datasets share no frame: " + ", ".join(str(m.root) for m in metas))
    sweeps, poses, described = _background(metas, names, background, background_frames, frames)
    types = dataset_types(metas[0])
    if detector is None:
        sigma = max(noise_sigma_of(m) for m in metas) if noise_sigma is None else noise_sigma
        detector = RoadsideDetector(noise_sigma=float(sigma), types=types)
    t0 = time.perf_counter()
    learned = learn_sensors(detector, sweeps, poses)
    del sweeps
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
                                         "sensors": names, "background": described,
                                         "types": "the scene's (dataset.json class_types)"
                                         if types else "built-in",
                                         "detector": getattr(detector, "name",
                                                             type(detector).__name__)}


DETECTOR_FILE = "detector.json"


def write_dataset_detections(folder, boxes, roots, frames, overwrite=False, about=None):
    """Write ``boxes`` as detection files of the first dataset of ``roots``, and
    ``about`` (what made them: the detector, its background) as ``detector.json``."""
    from ..output.datasets.common import write_json
    from .kitti_labels import write_detections

    paths = write_detections(Path(folder), boxes, roots[0], frames=frames, overwrite=overwrite)
    if about is not None:
        write_json(Path(folder) / DETECTOR_FILE, about, True)
    return paths


def read_about(folder):
    """What ``detector.json`` in a detections folder says (None: no such file, or not
    readable as one): the detector and background ``rls detect`` used."""
    import json

    path = Path(folder) / DETECTOR_FILE
    if not Path(folder).is_dir() or not path.is_file():
        return None
    try:
        about = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return about if isinstance(about, dict) else None
