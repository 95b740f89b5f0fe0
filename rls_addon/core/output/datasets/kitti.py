"""OpenPCDet's custom-dataset layout ("kitti" in ``rls dataset``), one root per sensor:

    <out>/<sensor>/points/NNNNNN.npy     float32 (N, 4): x y z intensity
    <out>/<sensor>/labels/NNNNNN.txt     one box a line: x y z dx dy dz heading Class
    <out>/<sensor>/meta/NNNNNN.json      every box (seen or not) with visibility, poses
    <out>/<sensor>/ImageSets/train.txt, val.txt
    <out>/<sensor>/dataset.json          classes, point features, frame, split, the
                                         background, the scene's class sizes
    <out>/<sensor>/background/points/NNNNNN.npy, background/meta/NNNNNN.json
                                         still sensors: sweep NNNNNN of the scene with
                                         every road user hidden (``background_writer``)

as ``pcdet/datasets/custom/custom_dataset.py`` reads it (``points/<id>.npy`` by
``np.load``, labels ``x y z dx dy dz heading_angle category_name``, classes
Vehicle/Pedestrian/Cyclist). Boxes and points share one frame: the sensor's own frame
(x forward, y left, z up), or with ``level`` a gravity-aligned frame at the sensor
(its yaw kept, pitch and roll removed; points mapped through the world, each with the
sensor's pose at its own time). OpenPCDet assumes a level sensor: a pitched pole LiDAR
without ``level`` has boxes turned out of the ground plane, which a heading alone
cannot express.
"""

import io
import json
from pathlib import Path

import numpy as np

from ...errors import RLSError
from ..io.atomic import atomic_write_bytes
from ..io.behind import WritesBehind
from ..io.names import sanitize_name
from .common import (
    BackgroundSweepWriter,
    Split,
    check_root,
    ensure_dir,
    frame_id,
    heading_in,
    level_frame,
    points_world,
    scan_settings,
    seam_notice,
    settings_differences,
    tilt_deg,
    write_json,
    write_text,
)

POINT_FORMATS = ("npy", "bin")


def class_name(category):
    """OpenPCDet's class name of an RLS label name: 'vehicle' -> 'Vehicle'."""
    return "".join(part.capitalize() for part in str(category).split("_"))


class KittiWriter:
    """The scan run's writer of the layout above (see ``run.Writer``).

    intensity_scale  1.0 (intensity 0..1) or 255.0 (0..255)
    points_format    'npy' (what OpenPCDet's custom loader reads) or 'bin' (raw float32)
    level            points and boxes in the gravity-aligned frame at the sensor
    min_points       boxes with fewer points are kept out of the label files (they stay
                     in meta/ with their visibility)
    background       each frame's files written behind the scan (``io.behind``)
    carriers         {sensor: the vehicle it rides on}: that vehicle is kept out of its
                     LiDAR's label files (a KITTI-style dataset never labels its ego: a
                     box around the sensor in every frame would be a free target), and
                     stays in meta/, named there as the carrier"""

    shardable = True
    works_out_later = True  # every write goes through ``WritesBehind.run`` (``behind.Later``)
    written_at_end = "the splits (ImageSets) and dataset.json are"  # finish

    def __init__(self, root, scene_name, intensity_scale=1.0, points_format="npy", level=False,
                 min_points=1, split=None, overwrite=False, resume=False, background=False,
                 carriers=None):
        if points_format not in POINT_FORMATS:
            raise RLSError(f"points format must be one of {', '.join(POINT_FORMATS)}")
        self.root, self.scene_name = Path(root), scene_name
        self.scale, self.points_format = float(intensity_scale), points_format
        self.level, self.min_points = bool(level), int(min_points)
        self.split = split or Split()
        self.overwrite, self.resume = bool(overwrite), bool(resume)
        self.notices = []
        self.class_types = None  # {class: [{size, objects}]}: the scene's road users
        self.carriers = dict(carriers or {})
        self._behind = WritesBehind(background)

    def sensor_root(self, sensor):
        return self.root / sanitize_name(sensor)

    def path(self, sensor, output, frame):
        return self.sensor_root(sensor) / "points" / f"{frame_id(frame)}.{self.points_format}"

    def incomplete(self, sensor, output, frame):
        """Points and labels of a frame whose meta (written last) is missing."""
        if self._meta(sensor, frame).exists():
            return []
        return [p for p in self.planned_files(sensor, output, frame)[:2] if p.exists()]

    def planned_files(self, sensor, output, frame):
        root = self.sensor_root(sensor)
        return [self.path(sensor, output, frame), root / "labels" / f"{frame_id(frame)}.txt",
                self._meta(sensor, frame)]

    def _meta(self, sensor, frame):
        return self.sensor_root(sensor) / "meta" / f"{frame_id(frame)}.json"

    def check(self, sensor, output, frame):
        check_root(self.root)
        frame_id(frame)

    def existing(self, sensor, output, frame, settings=None):
        """A complete earlier frame (points, labels and meta; the points read back with
        the meta's count), when resuming."""
        if not self.resume:
            return None
        meta, pts = self._meta(sensor, frame), self.path(sensor, output, frame)
        labels = self.sensor_root(sensor) / "labels" / f"{frame_id(frame)}.txt"
        if not (meta.is_file() and pts.is_file() and labels.is_file()):
            return None
        try:
            body = json.loads(meta.read_text())
            n = body["points"]
            rows = len(self._load(pts))
        except (OSError, ValueError, KeyError, TypeError):
            return None
        if settings is not None and self._differences(body, settings):
            return None
        return n if rows == n else None

    def _layout(self):
        return {"label_frame": "level" if self.level else "sensor",
                "intensity_scale": self.scale, "points_format": self.points_format}

    def _differences(self, body, settings):
        return settings_differences(body.get("settings"), settings, **self._layout())

    def stale_settings(self, sensor, output, frame, settings):
        """The settings an earlier frame of ``sensor`` was written with otherwise than
        ``settings`` say (empty: the same, or no such frame)."""
        try:
            body = json.loads(self._meta(sensor, frame).read_text())
        except (OSError, ValueError):
            return []
        return self._differences(body, settings) if isinstance(body, dict) else []

    def _load(self, path):
        if self.points_format == "npy":
            return np.load(path, mmap_mode="r")
        return np.fromfile(path, np.float32).reshape(-1, 4)

    def _points(self, sensor, points, info):
        """(float32 (N, 4) x y z intensity in the label frame, the label frame -> world)
        of a scan's sensor-frame ``points``."""
        if info.get("frame_space") != "sensor":
            raise RLSError("the KITTI layout needs sensor-frame points")
        start = np.asarray(info["sensor_pose_start"], np.float64)
        if self.level:
            frame_to_world = level_frame(start)
            to_frame = np.linalg.inv(frame_to_world)
            xyz = points_world(points, info) @ to_frame[:3, :3].T + to_frame[:3, 3]
        else:
            frame_to_world = start
            xyz = None  # the sensor-frame columns, as they are
            if tilt_deg(start) > 1.0 and not any(n.startswith(f"{sensor} leans")
                                                 for n in self.notices):
                self.notices.append(
                    f"{sensor} leans {tilt_deg(start):.1f} deg from level: its labels keep "
                    "only each box's heading in the sensor frame (OpenPCDet assumes a level "
                    "sensor); pass --level for points and boxes in a gravity-aligned frame "
                    "(the pitched sensor's roll/pitch are lost in KITTI labels otherwise)")
        arr = np.empty((len(points), 4), np.float32)
        if xyz is None:  # column by column: no (N, 3) float64 stack in between
            for k, f in enumerate("xyz"):
                arr[:, k] = points[f]
        else:
            arr[:, :3] = xyz
        arr[:, 3] = points["intensity"] * self.scale
        return arr, frame_to_world

    def _write_points(self, path, arr, overwrite):
        if self.points_format == "npy":
            buf = io.BytesIO()
            np.save(buf, arr)
            data = buf.getvalue()
        else:
            data = arr.tobytes()
        ensure_dir(path.parent)
        atomic_write_bytes(path, data, overwrite=overwrite)

    def write(self, sensor, output, frame, points, info):
        """Write a frame's points, labels and meta (meta last); with ``background``
        behind the scan (``io.behind``). Returns the points' path."""
        if info.get("frame_space") != "sensor":
            raise RLSError("the KITTI layout needs sensor-frame points")
        self._behind.run(self._write, sensor, output, frame, points, info)
        return self.path(sensor, output, frame)

    def _write(self, sensor, output, frame, points, info):
        root = self.sensor_root(sensor)
        fid = frame_id(frame)
        arr, frame_to_world = self._points(sensor, points, info)
        lines, boxes = [], []
        seam_notice(self.notices, sensor, info.get("objects", []))
        carrier = self.carriers.get(sensor)
        for b in info.get("objects", []):
            box = self._box(b, frame_to_world)
            boxes.append(dict(b, frame_box=box))
            if b["points"] >= self.min_points and b["object"] != carrier:
                lines.append(" ".join(f"{v:.6f}" for v in box["xyz"] + box["lwh"]
                                      + [box["heading"]]) + f" {class_name(b['category'])}")
        ow = self.overwrite or self.resume
        path = self.path(sensor, output, frame)
        self._write_points(path, arr, ow)
        write_text(root / "labels" / f"{fid}.txt", "".join(line + "\n" for line in lines), ow)
        # meta last: its presence marks a complete frame
        write_json(self._meta(sensor, frame), {
            "scene": self.scene_name, "sensor": sensor, "frame": frame,
            "points": int(len(points)), "timestamp_s": info.get("timestamp_s"),
            "frame_to_world": frame_to_world.tolist(),
            "label_frame": "level" if self.level else "sensor",
            "intensity_scale": self.scale, "objects": boxes,
            "sensor_pose_start": info["sensor_pose_start"],
            "sensor_poses": info.get("sensor_poses"), "device": info.get("device"),
            "settings": scan_settings(info, **self._layout()),
            **({"carrier": carrier} if carrier else {})}, ow)
        return path

    def background_writer(self, sweep, hidden):
        """The writer of background sweep ``sweep`` (``scan.background_sweeps``) of each
        sensor root: ``background/points/NNNNNN.npy`` and ``background/meta/NNNNNN.json``
        (NNNNNN the sweep's number), the points as the frames' (same frame, format and
        intensity scale), the meta as theirs without objects. ``hidden`` is the source
        with the road users hidden (``scene.hidden.WithoutLabels``): the meta names the
        labels it hid."""
        return KittiBackground(self, sweep, hidden)

    def _box(self, b, frame_to_world):
        """A box (sidecar dict) in the label frame: centre, l w h, heading."""
        if self.level:
            to_frame = np.linalg.inv(frame_to_world)
            centre = to_frame[:3, :3] @ np.asarray(b["world"]["centre"]) + to_frame[:3, 3]
            heading = heading_in(frame_to_world, np.asarray(b["world"]["rotation"]))
        else:  # the sensor frame at the box's own time
            centre = np.asarray(b["sensor"]["centre"])
            heading = b["sensor"]["heading_rad"]
        return {"xyz": [float(v) for v in centre], "lwh": [float(v) for v in b["size_lwh_m"]],
                "heading": float(heading)}

    def abort(self):
        """Frames already written are complete (a later --resume keeps them): the write
        under way ends first."""
        self.flush()

    def flush(self):
        """Wait for the frames being written behind the scan (raising what failed)."""
        self._behind.flush()

    def finish(self, run):
        """Splits and the dataset description, per sensor root, over every frame there
        (earlier runs' too)."""
        self.flush()
        for job in run.sensors:
            root = self.sensor_root(job.name)
            ids = sorted(p.stem for p in (root / "meta").glob("*.json")) \
                if (root / "meta").is_dir() else []
            # drawn over every frame, so a frame's side never depends on its labels
            val = set(self.split.val(ids))
            labelled = {i: _has_labels(root / "labels" / f"{i}.txt") for i in ids}
            listed = [i for i in ids if labelled[i]]
            unlabelled = [i for i in ids if not labelled[i]]
            ensure_dir(root / "ImageSets")
            write_text(root / "ImageSets" / "train.txt",
                       "".join(i + "\n" for i in listed if i not in val), True)
            write_text(root / "ImageSets" / "val.txt",
                       "".join(i + "\n" for i in listed if i in val), True)
            if unlabelled:
                self.notices.append(_unlabelled_notice(job.name, unlabelled, len(ids)))
            classes = [class_name(c) for c in job.settings.output.object_classes]
            write_json(root / "dataset.json", {
                "layout": "OpenPCDet custom dataset", "scene": self.scene_name,
                "sensor": job.name, "device": job.preset.id, "class_names": classes,
                "point_features": ["x", "y", "z", "intensity"],
                "points_format": self.points_format, "intensity_scale": self.scale,
                "frame": "level (gravity-aligned at the sensor)" if self.level
                else "sensor (x forward, y left, z up)",
                "min_points_per_label": self.min_points, "split": self.split.to_dict(),
                "frames": len(ids), "val_frames": sum(i in val for i in listed),
                "frames_without_labels": unlabelled,
                "background": self._background_record(root),
                "class_types": self.class_types}, True)

    def _background_record(self, root):
        """What dataset.json says of the sensor's background sweeps (None: none)."""
        metas = sorted((root / "background" / "meta").glob("*.json")) \
            if (root / "background" / "meta").is_dir() else []
        if not metas:
            return None
        first = json.loads(metas[0].read_text())
        return {"folder": "background", "sweeps": len(metas),
                "scene_frame": first.get("scene_frame"),
                "hidden_labels": first.get("hidden_labels"),
                "what": "sweeps of the scene with every road user hidden (vehicles, "
                        "pedestrians, cyclists, parked ones included), the device's noise "
                        "in each: the background a deployed unit learns; points and meta "
                        "as the frames'"}


class KittiBackground(BackgroundSweepWriter):
    """A ``run.Writer`` of one background sweep into the sensor roots of a
    ``KittiWriter`` (see ``KittiWriter.background_writer``)."""

    def _root(self, sensor):
        return self.dataset.sensor_root(sensor) / "background"

    def path(self, sensor, output, frame):
        return self._root(sensor) / "points" / f"{frame_id(self.sweep)}.{self.dataset.points_format}"

    def _meta(self, sensor):
        return self._root(sensor) / "meta" / f"{frame_id(self.sweep)}.json"

    def write(self, sensor, output, frame, points, info):
        arr, frame_to_world = self.dataset._points(sensor, points, info)
        path = self.path(sensor, output, frame)
        self.dataset._write_points(path, arr, self.overwrite)
        write_json(self._meta(sensor), {
            "scene": self.dataset.scene_name, "sensor": sensor, "sweep": self.sweep,
            "scene_frame": frame, "points": int(len(points)), **self.hidden_record(),
            "frame_to_world": frame_to_world.tolist(),
            "label_frame": "level" if self.dataset.level else "sensor",
            "intensity_scale": self.dataset.scale, "objects": [],
            "sensor_pose_start": info["sensor_pose_start"],
            "sensor_poses": info.get("sensor_poses"), "device": info.get("device"),
            "settings": scan_settings(info, **self.dataset._layout())}, self.overwrite)
        return path


def _has_labels(path):
    """Whether a frame's label file holds a box (a missing file holds none)."""
    try:
        return bool(Path(path).read_text().strip())
    except FileNotFoundError:
        return False


def _unlabelled_notice(sensor, ids, total):
    """What a run says of the frames of ``sensor`` left out of its ImageSets."""
    some = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
    return (f"{len(ids)} of {sensor}'s {total} frames have no box in their label file "
            f"({some}): they are left out of ImageSets/train.txt and val.txt, because "
            "OpenPCDet's custom dataset fails on an empty label file (create_custom_infos "
            "indexes its empty box array) and its training skips frames without boxes; "
            "their points, labels and meta are written, and dataset.json lists them "
            "under frames_without_labels")


def read_labels(path):
    """(boxes (N, 7) float, class names) of a label file (for tests and users)."""
    rows = [line.split() for line in Path(path).read_text().splitlines() if line.strip()]
    if not rows:
        return np.zeros((0, 7)), []
    return np.array([[float(v) for v in r[:7]] for r in rows]), [r[7] for r in rows]


__all__ = ["KittiBackground", "KittiWriter", "POINT_FORMATS", "class_name", "read_labels"]
