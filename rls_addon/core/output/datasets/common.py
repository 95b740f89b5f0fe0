"""What the dataset writers share: frame ids, file writing, splits, frames of
reference."""

import json
import math
import os
from pathlib import Path

import numpy as np

from ...errors import OutputError, SettingsError
from ..io import json_text
from ..io.atomic import atomic_write_bytes, writable_folder
from ...points import xyz
from ..io.sidecar import points_to_world


def scan_settings(info, **layout):
    """What a dataset frame records of how it was made, to resume only frames of the
    same settings: the scan's settings as its sidecar would state them
    (``io.sidecar.recorded_settings``: device, seed, frame space, every effect), and the
    layout's own options (``layout``), as JSON holds them."""
    from ..io.sidecar import recorded_settings

    rec = {k: v for k, v in recorded_settings(info).items()
           if k not in ("format", "fields", "point_type")}
    return json.loads(json.dumps(dict(rec, **layout), allow_nan=False, default=_plain_value))


def settings_differences(stored, settings, **layout):
    """The names of the settings (``scan.session.settings_record``) and layout options
    that a frame's ``stored`` record (``scan_settings``) states otherwise; a frame
    written before records existed differs in all of them."""
    want = json.loads(json.dumps(dict(settings, **layout), allow_nan=False,
                                 default=_plain_value))
    stored = stored if isinstance(stored, dict) else {}
    return [k for k in want if stored.get(k) != want[k]]


def _plain_value(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"not JSON: {type(v).__name__}")


def frame_id(frame):
    """The six-digit id of a frame, as KITTI-style datasets name their files."""
    if frame < 0:
        raise OutputError(f"frame {frame}: dataset file names need frames >= 0")
    return f"{int(frame):06d}"


def write_json(path, data, overwrite):
    atomic_write_bytes(path, (json_text.dumps(data, indent=1) + "\n").encode("utf-8"),
                       overwrite=overwrite)


def write_text(path, text, overwrite):
    atomic_write_bytes(path, text.encode("utf-8"), overwrite=overwrite)


def check_root(root):
    writable_folder(root)
    return Path(root)


def points_world(points, info):
    """(N, 3) world positions of sensor-frame points, each through the sensor's pose at
    its own firing time (``io.sidecar.points_to_world``)."""
    return xyz(points_to_world(points, info))


def level_frame(sensor_to_world):
    """The gravity-aligned frame at a sensor (4x4, frame -> world): its origin, world z
    up, x along the sensor's x axis turned level (its yaw; pitch and roll removed)."""
    m = np.asarray(sensor_to_world, np.float64)
    x = m[:3, 0].copy()
    x[2] = 0.0
    if np.linalg.norm(x) < 1e-9:  # looking straight up or down: its z axis gives the yaw
        x = -np.sign(m[2, 0]) * m[:3, 2]
        x[2] = 0.0
    x /= np.linalg.norm(x)
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2] = x, np.cross([0.0, 0.0, 1.0], x), (0.0, 0.0, 1.0)
    out[:3, 3] = m[:3, 3]
    return out


def tilt_deg(sensor_to_world):
    """How far a sensor's z axis leans from the vertical (degrees)."""
    z = np.asarray(sensor_to_world, np.float64)[:3, 2]
    return math.degrees(math.acos(max(-1.0, min(1.0, z[2] / max(np.linalg.norm(z), 1e-12)))))


def heading_in(frame_to_world, box_rotation_world):
    """Yaw of a box's length axis in a frame (radians, counter-clockwise about z)."""
    r = np.linalg.inv(np.asarray(frame_to_world, np.float64))[:3, :3] @ box_rotation_world
    return float(math.atan2(r[1, 0], r[0, 0]))


class Split:
    """Which frame ids are for validation: a seeded share, or a frame range."""

    def __init__(self, val_share=0.2, seed=0, val_frames=None):
        if not 0.0 <= val_share < 1.0:
            raise SettingsError(f"validation share must be in [0, 1), got {val_share}")
        self.val_share, self.seed, self.val_frames = float(val_share), int(seed), val_frames

    def val(self, ids):
        """The validation subset of ``ids`` (sorted strings)."""
        ids = sorted(ids)
        if self.val_frames is not None:
            lo, hi = self.val_frames
            return sorted(i for i in ids if lo <= int(i) <= hi)
        rng = np.random.default_rng(self.seed)
        order = rng.permutation(len(ids))
        return sorted(ids[j] for j in order[:int(round(self.val_share * len(ids)))])

    def to_dict(self):
        return {"val_share": self.val_share, "seed": self.seed,
                "val_frames": list(self.val_frames) if self.val_frames else None}


def seam_notice(notices, sensor, boxes):
    """Add (once per sensor) the notice that boxes lie on the sweep's seam."""
    if any(b.get("split_by_sweep_seam") for b in boxes) and not any(
            n.startswith(f"boxes of {sensor} lie") for n in notices):
        notices.append(f"boxes of {sensor} lie on its sweep's seam (scanned at the start "
                       "and at the end of the sweep, a period apart, so their points form "
                       "two clusters and each box holds the larger one); move the seam off "
                       "the road with --sweep-start (e.g. 180: behind the sensor)")


class BackgroundSweepWriter:
    """What the layouts' writers of a background sweep share (a ``run.Writer`` of one
    sweep, ``scan.background_sweeps``): a point file and its description (``_meta``,
    written last: its presence marks a complete sweep), in the layout's ``dataset``
    writer's folders; ``hidden`` is the source with the road users hidden. Sweeps are
    scanned again on ``--resume`` (a handful of scans), replacing what was there."""

    shardable = False

    def __init__(self, dataset, sweep, hidden):
        self.dataset, self.sweep, self.hidden = dataset, int(sweep), hidden
        self.overwrite = dataset.overwrite or dataset.resume

    def _meta(self, sensor):
        raise NotImplementedError

    def planned_files(self, sensor, output, frame):
        return [self.path(sensor, output, frame), self._meta(sensor)]

    def incomplete(self, sensor, output, frame):
        path = self.path(sensor, output, frame)
        return [path] if path.exists() and not self._meta(sensor).exists() else []

    def check(self, sensor, output, frame):
        self.dataset.check(sensor, output, frame)

    def existing(self, sensor, output, frame, settings=None):
        return None

    def hidden_record(self):
        """What the sweep's description says of the road users hidden."""
        from ...labels import label_name

        return {"hidden_labels": sorted(label_name(i) for i in self.hidden.label_ids),
                "hidden_objects": len(self.hidden.hidden)}

    def finish(self, run):
        """Nothing beyond the sweep's files (the dataset's description names them)."""

    def abort(self):
        """A sweep's files are complete or its description is missing (scanned again)."""

    def flush(self):
        """Files are written in place."""


def ensure_dir(path):
    os.makedirs(path, exist_ok=True)
    return path
