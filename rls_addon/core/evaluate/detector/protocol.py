"""The detector protocol: what ``rls detect``, ``rls study --evaluate`` and the tests ask
of a detector of still roadside LiDARs, so another one (a learned detector where a GPU is
present) plugs in without touching them, as the casters do.

    class Detector(Protocol):
        name: str                                   # said in the outputs
        def learn(self, sensor, sweeps, pose): ...  # -> what it learned of one sensor
        def view(self, learned, points, pose): ...  # -> one frame of that sensor, as kept
        def detect(self, seen, frame): ...          # [(learned, view)] -> Boxes (fused)

- ``learn(sensor, sweeps, pose)``: the background of one still sensor (its name, a list
  of sweeps: point arrays in the sensor frame, x forward, y left, z up, a structured
  array with x, y, z (and ring) or (N, >=3) x y z ...; ``pose`` (4, 4) sensor -> world).
  Returns anything (picklable: a study sends it between processes).
- ``view(learned, points, pose)``: what the detector keeps of one frame of that sensor
  (RLS's roadside detector: its foreground in the world; a learned detector: the points).
  A study keeps one view per candidate and frame and fuses any set of them.
- ``detect(seen, frame)``: the world ``Boxes`` of one frame seen by one sensor or by
  several fused (early fusion): ``seen`` is [(learned, view)] in a fixed order.

Only x, y, z (and ring) of the points may be read: never labels, instances or ghost
flags, which are ground truth. ``learn_sensors`` and ``detect_frame`` drive a detector
over dicts of sensors."""

from typing import Any, Protocol, Sequence

import numpy as np

from ...errors import InputError


class Detector(Protocol):
    name: str

    def learn(self, sensor: str, sweeps: Sequence, pose: np.ndarray) -> Any: ...

    def view(self, learned: Any, points, pose: np.ndarray) -> Any: ...

    def detect(self, seen: Sequence[tuple], frame: int): ...


def check_pose(sensor, pose):
    """``pose`` as a (4, 4) float64 matrix; ``InputError`` naming ``sensor`` if it is not
    a finite one."""
    m = np.asarray(pose, np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"sensor {sensor!r}: the pose must be a finite 4x4 matrix")
    return m


def _by_sensor(items, poses, what):
    """(items, poses) as dicts with the same keys, in the given order (a sequence is
    keyed by position)."""
    if not isinstance(items, dict):
        items = dict(enumerate(items))
    if not isinstance(poses, dict):
        poses = dict(zip(items, poses))
    missing = [k for k in items if k not in poses]
    if missing:
        raise InputError(f"no sensor pose for {missing} ({what})")
    return items, {k: check_pose(k, poses[k]) for k in items}


def learn_sensors(detector, sweeps_by_sensor, poses):
    """{sensor: what ``detector`` learned of it} from ``sweeps_by_sensor`` ({sensor: list
    of sweeps}, or a sequence in the order of ``poses``) and ``poses``. A bare point
    array is one sweep."""
    sweeps, poses = _by_sensor(sweeps_by_sensor, poses, "learning")
    out = {}
    for key, fr in sweeps.items():
        if fr is None or (isinstance(fr, np.ndarray) and (fr.dtype.names or fr.ndim == 2)):
            fr = [fr]
        out[key] = detector.learn(key, list(fr), poses[key])
    return out


def detect_frame(detector, learned, points_by_sensor, poses, frame=0):
    """``detector``'s ``Boxes`` of one frame: ``points_by_sensor`` ({sensor: points}, or a
    sequence in ``learned``'s order) fused, each sensor at its pose."""
    if not learned:
        raise InputError("the detector has learned no sensor: learn its background first")
    if not isinstance(points_by_sensor, dict):
        points_by_sensor = dict(zip(learned, points_by_sensor))
    points, poses = _by_sensor(points_by_sensor,
                               poses if isinstance(poses, dict) else dict(zip(learned, poses)),
                               "detection")
    seen = []
    for key, pts in points.items():
        if key not in learned:
            raise InputError(f"no background was learned for sensor {key!r}")
        seen.append((learned[key], detector.view(learned[key], pts, poses[key])))
    return detector.detect(seen, frame)
