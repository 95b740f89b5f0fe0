"""Traffic for the sample scenes: vehicles, cyclists and pedestrians moving along routes
of straights and circular arcs, keyed once a frame, and parked vehicles.

A ``Route`` is a turtle path from a start point and heading, made of
``straight(length, speed)`` and ``turn(radius, degrees, speed)`` pieces (positive
degrees turn left). Between pieces the speed changes at ``accel`` m/s^2: a vehicle
brakes before a slower piece (a turn) and speeds up after it, never jumping. A mover is
placed on its route by ``s0``, the distance along the route at the scene's first frame.

Every object is a box modelled along its local +X (length), +Y (width) and +Z (height)
with its origin on the ground under its centre, and a mover is keyed at every frame
(location x, y, z and rotation z, linear, written in bulk into F-curves): its
ground-truth box (the mesh's own box in its own axes) heads along the route's tangent,
through the turns too. Everything here is deterministic.
"""

import math

import bpy
import numpy as np

from .build import box

SAMPLE_M = 0.05  # route sampling step (m)


class Route:
    """A path of straights and arcs from ``(x, y)`` heading ``heading_deg`` (0: +x,
    90: +y), with a speed per piece; ``z`` is the height of the surface it runs on (a
    number, or a function of an (N, 2) array of xy giving N heights)."""

    def __init__(self, x, y, heading_deg, z=0.0, accel=2.0):
        self.start = (float(x), float(y))
        self.heading = math.radians(heading_deg)
        self.z = z
        self.accel = float(accel)
        self.pieces = []  # (kind, length or radius, radians or None, speed)
        self._table = None

    def straight(self, length, speed):
        self.pieces.append(("line", float(length), None, float(speed)))
        self._table = None
        return self

    def turn(self, radius, degrees, speed):
        self.pieces.append(("arc", float(radius), math.radians(degrees), float(speed)))
        self._table = None
        return self

    @property
    def length(self):
        return float(self.table()[0][-1])

    @property
    def duration(self):
        return float(self.table()[4][-1])

    def table(self):
        """Samples along the route: (s, x, y, yaw, t): distance, position, heading
        (radians, continuous) and the time to get there from the start."""
        if self._table is not None:
            return self._table
        x, y = self.start
        h = self.heading
        xs, ys, hs, ss = [x], [y], [h], [0.0]
        bounds, speeds = [], []  # each piece's [s0, s1] and speed
        for kind, a, ang, v in self.pieces:
            s0 = ss[-1]
            length = a if kind == "line" else a * abs(ang)
            n = max(1, int(math.ceil(length / SAMPLE_M)))
            u = np.arange(1, n + 1) / n
            if kind == "line":
                px, py, ph = x + u * length * math.cos(h), y + u * length * math.sin(h), \
                    np.full(n, h)
            else:
                side = 1.0 if ang > 0 else -1.0  # the centre is on the left for a left turn
                cx, cy = x - side * a * math.sin(h), y + side * a * math.cos(h)
                ph = h + u * ang
                px, py = cx + side * a * np.sin(ph), cy - side * a * np.cos(ph)
            xs += list(px)
            ys += list(py)
            hs += list(ph)
            ss += list(s0 + u * length)
            x, y, h = float(px[-1]), float(py[-1]), float(ph[-1])
            bounds.append((s0, ss[-1]))
            speeds.append(v)
        s = np.array(ss)
        # the fastest speed that reaches every piece's speed at its start braking (and
        # leaves it accelerating) at self.accel: min over pieces of sqrt(v^2 + 2 a d)
        v = np.full(len(s), np.inf)
        for (b0, b1), vp in zip(bounds, speeds):
            d = np.maximum(0.0, np.maximum(b0 - s, s - b1))
            v = np.minimum(v, np.sqrt(vp * vp + 2.0 * self.accel * d))
        dt = np.diff(s) * 0.5 * (1.0 / v[1:] + 1.0 / v[:-1])
        t = np.concatenate([[0.0], np.cumsum(dt)])
        self._table = (s, np.array(xs), np.array(ys), np.array(hs), t)
        return self._table

    def time_at(self, s):
        ss, _, _, _, t = self.table()
        return float(np.interp(s, ss, t))

    def poses(self, times):
        """(N, 3) xyz and (N,) yaw at route times ``times`` (seconds from its start)."""
        ss, xs, ys, hs, tt = self.table()
        times = np.asarray(times, float)
        if times.min() < -1e-9 or times.max() > tt[-1] + 1e-9:
            raise ValueError(f"route times {times.min():.2f}..{times.max():.2f} s outside "
                             f"0..{tt[-1]:.2f} s: lengthen the route or move the mover")
        s = np.interp(times, tt, ss)
        xy = np.stack([np.interp(s, ss, xs), np.interp(s, ss, ys)], axis=1)
        z = self.z(xy) if callable(self.z) else np.full(len(xy), float(self.z))
        return np.column_stack([xy, z]), np.interp(s, ss, hs)


def frame_times(scene):
    """Seconds from the first frame for each frame of ``scene``, and the frames."""
    frames = np.arange(scene.frame_start, scene.frame_end + 1)
    fps = scene.render.fps / scene.render.fps_base
    return (frames - frames[0]) / fps, frames


def body(coll, name, size, mat, clearance=0.0):
    """A box of ``size`` (length, width, height) along local x, y, z, its origin on the
    ground under its centre, ``clearance`` metres above it."""
    L, W, H = size
    return box(coll, name, (-L / 2, -W / 2, clearance), (L / 2, W / 2, clearance + H), mat)


def key_motion(obj, frames, xyz, yaw):
    """Key ``obj`` at ``frames`` to locations ``xyz`` (N, 3) and headings ``yaw`` (N,),
    linear, in one action: F-curves filled with ``foreach_set``, not a key at a time."""
    obj.location = tuple(map(float, xyz[0]))
    obj.rotation_euler = (0.0, 0.0, float(yaw[0]))
    obj.animation_data_create()
    action = bpy.data.actions.new(f"{obj.name} motion")
    obj.animation_data.action = action
    linear = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value
    n = len(frames)
    for path, index, values in (("location", 0, xyz[:, 0]), ("location", 1, xyz[:, 1]),
                                ("location", 2, xyz[:, 2]), ("rotation_euler", 2, yaw)):
        fc = action.fcurve_ensure_for_datablock(obj, path, index=index)
        fc.keyframe_points.add(n)
        co = np.column_stack([frames, values]).astype(np.float32).ravel()
        fc.keyframe_points.foreach_set("co", co)
        fc.keyframe_points.foreach_set("interpolation", [linear] * n)
        fc.update()
    return obj


def mover(scene, coll, name, size, mat, route, s0, clearance=0.0):
    """A box travelling ``route`` from ``s0`` metres along it at the first frame of
    ``scene``, keyed at every frame."""
    times, frames = frame_times(scene)
    xyz, yaw = route.poses(route.time_at(s0) + times)
    return key_motion(body(coll, name, size, mat, clearance), frames, xyz, yaw)


def parked(coll, name, size, mat, x, y, heading_deg, z=0.0, clearance=0.3):
    """A still box at (x, y) heading ``heading_deg``."""
    obj = body(coll, name, size, mat, clearance)
    obj.location = (float(x), float(y), float(z))
    obj.rotation_euler = (0.0, 0.0, math.radians(heading_deg))
    return obj
