"""JSON metadata written next to a cloud file (same stem, ``.json``).

The caller supplies the contents (device preset and source, sensor pose,
frame, seed, effect settings, label map, software version). Readers of the
cloud (``rls metrics``) look at two keys: ``"frame"`` (``"sensor"`` or
``"world"``: the coordinate frame of the points) and ``"sensor_to_world"``
(4x4 nested list, row-major, rigid: maps sensor-frame points to world; the LiDAR
object's matrix without its scale, ``frame.sensor_frame``), and for a sensor
that moved during its sweep ``"sensor_poses"``; ``points_to_world`` reads all three.
"""

import json
import math
import pathlib

import numpy as np

from ...errors import InputError, OutputError
from ...points import xyz
from ...scene.motion import poses_at
from . import json_text
from .atomic import atomic_write_bytes


def sidecar_path(cloud_path):
    return pathlib.Path(cloud_path).with_suffix(".json")


def _plain(obj):
    """JSON-ready copy: numpy values to Python, non-finite floats to null."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return _plain(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, pathlib.PurePath):
        return str(obj)
    return obj


def write_sidecar(cloud_path, info, overwrite=False):
    """Write ``info`` as JSON beside ``cloud_path``; returns the JSON path."""
    path = sidecar_path(cloud_path)
    try:
        text = json_text.dumps(info, indent=2, sort_keys=True, plain=_plain)
    except (TypeError, ValueError) as exc:
        raise OutputError(f"cannot write {path}: metadata is not JSON-serialisable ({exc})") from None
    return atomic_write_bytes(path, (text + "\n").encode("utf-8"), overwrite=overwrite)


def recorded_settings(info):
    """The settings a sidecar states, by name (``scan.session.settings_record``'s names,
    and the writer's format, fields and point type)."""
    rec = {"device": (info.get("device") or {}).get("id"), "seed": info.get("seed"),
           "frame_space": info.get("frame_space")}
    rec.update({k: v for k, v in (info.get("effects") or {}).items() if k != "substeps_used"})
    rec.update({k: info.get(k) for k in ("format", "fields", "point_type")})
    return rec


def settings_differences(info, expected):
    """The names of the settings in ``expected`` that sidecar ``info`` states otherwise
    (compared as JSON holds them)."""
    got = recorded_settings(info)
    want = json.loads(json.dumps(_plain(expected), allow_nan=False))
    return [k for k in want if got.get(k) != want[k]]


def read_sidecar(cloud_path):
    """The sidecar dict of ``cloud_path``, or ``None`` if there is none."""
    path = sidecar_path(cloud_path)
    if not path.is_file():
        return None
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read sidecar {path}: {exc}") from None
    _check_sidecar_format(info, path, pathlib.Path(cloud_path))
    return info


def _check_sidecar_format(info, path, cloud):
    """``InputError`` when the sidecar describes a cloud of another format than
    ``cloud``'s: 'x.pcd' and 'x.ply' share 'x.json', so a run with --overwrite in
    another format replaces the sidecar of the earlier cloud (its frame, pose and seed
    then describe other points). The writer removes that cloud (``writer``); one copied
    back, or left by an older RLS, is refused here."""
    fmt = info.get("format") if isinstance(info, dict) else None
    if not isinstance(fmt, str):
        return
    # the extension of the format's files (formats.FORMATS, which this module may not
    # import: pcd_*, ply_* and las write .pcd, .ply and .las; a bag has no sidecar)
    ext = {"pcd": ".pcd", "ply": ".ply", "las": ".las"}.get(fmt.split("_")[0])
    if ext and cloud.suffix.lower() != ext:
        raise InputError(f"sidecar {path} describes a {fmt} cloud ({cloud.stem}{ext}), not "
                         f"{cloud.name}: a later run wrote that format under the same name "
                         f"(--overwrite); scan {cloud.name} again or read the {ext} file")


def points_to_world(points, info, where="the cloud"):
    """A copy of ``points`` in the world frame, as its sidecar ``info`` says they are:
    world-frame points as they are; sensor-frame points through ``sensor_to_world``, or
    for a sensor that moved during its sweep through its pose at each point's own time
    (the sidecar's ``sensor_poses`` knots). ``InputError`` naming ``where`` when the
    sidecar cannot say."""
    space = info.get("frame_space")
    if space is None and isinstance(info.get("frame"), str):
        space = info["frame"]
    if space in (None, "world"):
        return points
    if space != "sensor":
        raise InputError(f"sidecar of {where}: unknown coordinate frame {space!r} "
                         "(expected sensor or world)")
    knots = info.get("sensor_poses")
    out = points.copy()
    local = xyz(points)
    if knots:
        try:
            poses = poses_at(knots["times_s"], knots["matrices"], points["time"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"sidecar of {where}: unreadable sensor_poses ({exc})") from None
        w = np.einsum("nij,nj->ni", poses[:, :3, :3], local) + poses[:, :3, 3]
    else:
        m = info.get("sensor_to_world")
        m = np.asarray(m, dtype=np.float64) if m is not None else None
        if m is None or m.shape != (4, 4) or not np.isfinite(m).all():
            raise InputError(f"sidecar of {where} says the points are in the sensor frame but "
                             "has no valid 4x4 sensor_to_world")
        w = local @ m[:3, :3].T + m[:3, 3]
    out["x"], out["y"], out["z"] = w[:, 0], w[:, 1], w[:, 2]
    return out
