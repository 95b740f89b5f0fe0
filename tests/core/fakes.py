"""A scene source without Blender, for the core's orchestration tests: a few boxes,
some of them moving by functions of time, and sensors with fixed or moving poses."""

from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from rls_addon.core.scene.geometry import MaterialInfo
from rls_addon.core.scene.instances import Instance
from rls_addon.core.device.presets import preset_from_dict
from rls_addon.core.scene.source import Mobility, SceneRead

from .scenes import BOX_TRIS, box_vertices


def small_preset(channels=8, steps=360, max_m=60.0, noise=0.0, pid="small8"):
    """A spinning 8-channel device of 2,880 rays a frame at 10 Hz."""
    return preset_from_dict({
        "id": pid, "name": "Small test lidar", "family": "spinning", "source": "tests",
        "frequency_hz": 10.0, "range": {"min_m": 0.3, "max_m": max_m, "noise_sigma_m": noise},
        "scan": {"channels": channels, "upper_fov_deg": 10.0, "lower_fov_deg": -25.0,
                 "points_per_second": channels * steps * 10}})


def translation(p):
    m = np.eye(4)
    m[:3, 3] = p
    return m


class FakeScene:
    """A scene source (``core.source.SceneSource``).

    boxes    {name: (lo, hi, label)} in the box's own frame
    motion   {name: f(seconds since frame 0) -> 4x4}; others stand at the identity
    sensors  {name: f(seconds) -> 4x4}
    fps      frames per second (frame f starts at (f - 1) / fps s)"""

    def __init__(self, boxes, sensors, motion=None, fps=10.0, name="fake"):
        self.name, self.fps, self.frame_start = name, fps, 1
        self.boxes, self.sensors, self.motion = boxes, sensors, dict(motion or {})
        self.frame = 1
        self.calls = {"read": 0, "state": 0, "set_frame": 0}
        self.materials = [MaterialInfo("default"), MaterialInfo("grey", 0.5)]

    def seconds(self, frame, t=0.0):
        return (frame - 1) / self.fps + t

    def current_frame(self):
        return self.frame

    def set_frame(self, frame):
        self.calls["set_frame"] += 1
        self.frame = int(frame)

    def _matrix(self, name, seconds):
        f = self.motion.get(name)
        return np.eye(4) if f is None else np.asarray(f(seconds), float)

    def sensor_pose(self, sensor):
        return np.asarray(self.sensors[sensor](self.seconds(self.frame)), float)

    def _instance(self, name, seconds):
        lo, hi, label = self.boxes[name]
        return Instance(name, name, "", label, box_vertices(lo, hi), BOX_TRIS.copy(),
                        np.ones(12, np.int32), self._matrix(name, seconds),
                        np.array([1], np.int32), mesh_id=1 + sorted(self.boxes).index(name))

    def sensor_may_move(self, sensor):
        return sensor in getattr(self, "moving_sensors", ())

    def read(self, centre, max_range, exclude):
        self.calls["read"] += 1
        t = self.seconds(self.frame)
        out = [self._instance(n, t) for n in sorted(self.boxes) if n not in exclude]
        return SceneRead(out, self.materials, {"objects": len(out), "culled_by_range": 0})

    def mobility(self, instances, sensor):
        moving = [k for k, i in enumerate(instances) if i.key in self.motion]
        return Mobility(moving, set(), sensor in getattr(self, "moving_sensors", ()))

    @contextmanager
    def _sweep(self, frame):
        yield _FakeSweep(self, frame)

    def sweep(self, frame, period):
        return self._sweep(frame)


class _FakeSweep:
    def __init__(self, scene, frame):
        self.scene, self.frame = scene, frame

    def state(self, t, keys, deform_keys, sensor):
        self.scene.calls["state"] += 1
        s = self.scene.seconds(self.frame, t)
        mats = {k: self.scene._matrix(k, s) for k in keys}
        return mats, {}, np.asarray(self.scene.sensors[sensor](s), float)

    def instance_at(self, t, instance):
        return replace(instance, matrix=self.scene._matrix(instance.key,
                                                           self.scene.seconds(self.frame, t)))


def street(car_speed=0.0):
    """A ground slab, a wall, and a car driving along +y at ``car_speed`` m/s, seen by a
    still sensor 'pole' and a second one 'mast'."""
    boxes = {"ground": ((-40, -40, -1.2), (40, 40, -1.0), 1),
             "wall": ((10, -15, -1.0), (11, 15, 4.0), 4),
             "car": ((-2.25, -0.9, -1.0), (2.25, 0.9, 0.5), 11)}
    motion = {"car": lambda s: translation((4.0, -8.0 + car_speed * s, 0.0))} if car_speed \
        else {}
    if not car_speed:
        boxes["car"] = ((1.75, -8.9, -1.0), (6.25, -7.1, 0.5), 11)
    sensors = {"pole": lambda s: translation((0.0, 0.0, 0.5)),
               "mast": lambda s: translation((-3.0, 2.0, 1.0))}
    return FakeScene(boxes, sensors, motion)


def numpy_factory(name):
    """A ``casting.caster_factory`` stand-in: every backend is the exact numpy one."""
    from rls_addon.core.casting import NumpyCaster

    return NumpyCaster, None
