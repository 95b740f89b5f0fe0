"""Ground truth for perception: a 3D box for every object of an object class (vehicle,
pedestrian, cyclist by default) near a sensor, in the world and in the sensor frame,
with how well the sensor saw it.

The box of an object is the box of its own mesh in its own axes: length along its
local x, width along y, height along z (scale applied), centred on that box, turned
as the object is. It is placed at a *reference time* of its own: the median firing
time of the object's points when the sensor saw it, else the time the sensor's beam
pointed at the object's centre. A spinning sensor scans an object within a few
milliseconds, so points and box agree even for a car driving fast; the sweep start
would leave a car at 15 m/s up to 1.5 m from where its points are.

Visibility, per box and sensor:
- ``points``: returns (ghosts excluded) that carry the object's instance id;
- ``points_in_box``: returns (ghosts excluded, any object) inside the box grown by
  ``margin`` (3 sigma of the range noise + 2 cm, so noise on a surface does not push
  its points out);
- ``visible_share``: of the rays whose path crosses the box within range and that hit
  this object or something in front of the box, the share that hit the object: 1 in
  full view, 0 behind an occluder, NaN when no ray crosses the box (out of the field
  of view or range). Every object of a class within the sensor's reach is listed,
  seen or not (``seen`` false), so users can filter as KITTI does.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..world.bodies import ray_meets_sphere
from ..labels import label_name
from ..scene.motion import Track, polar

BOX_MARGIN_M = 0.02


@dataclass
class ObjectBox:
    instance: int
    name: str
    label: int
    size: np.ndarray        # (3,) length, width, height (m): the object's local x, y, z
    pose: np.ndarray        # (4, 4) box frame (centre, object axes) -> world
    time: float             # reference time, seconds since the sweep start
    velocity: np.ndarray    # (3,) m/s, world
    sensor_pose: np.ndarray  # (4, 4) the sensor's pose at ``time``
    origin: np.ndarray = None  # (3,) the object's own origin (its matrix) at ``time``
    points: int = 0
    points_in_box: int = 0
    visible_share: float = math.nan
    rays_on_box: int = 0
    seam: bool = False  # its points came from both ends of the sweep (see split_at_seam)
    start_matrix: np.ndarray = None  # (4, 4) the object's matrix at the sweep start

    @property
    def category(self):
        return label_name(self.label)

    @property
    def seen(self):
        return self.points > 0

    @property
    def centre(self):
        return self.pose[:3, 3]

    @property
    def heading(self):
        """Yaw (radians, counter-clockwise from world +X) of the box's length axis."""
        return float(math.atan2(self.pose[1, 0], self.pose[0, 0]))

    def in_frame(self, to_frame):
        """The box pose in another frame: ``to_frame`` maps world to that frame."""
        return np.asarray(to_frame, np.float64) @ self.pose

    def in_sensor(self):
        """The box pose in the sensor frame at the reference time."""
        return self.in_frame(np.linalg.inv(self.sensor_pose))

    def _at_start(self):
        """Where the box was at the sweep start (the time of the sidecar's
        ``sensor_pose_start``): what a simulator's per-tick poses give, e.g. OPV2V's
        ``true_ego_pos`` beside its ``lidar_pose``."""
        centre, rot, origin = _box_at(self, self.start_matrix)
        return {"centre": centre.tolist(), "origin": origin.tolist(), "rotation": rot.tolist(),
                "heading_rad": float(math.atan2(rot[1, 0], rot[0, 0]))}

    def to_dict(self):
        sensor = self.in_sensor()
        return {
            "instance": self.instance, "object": self.name, "label": self.label,
            "category": self.category, "time_s": self.time, "seen": self.seen,
            "points": self.points, "points_in_box": self.points_in_box,
            "visible_share": None if not math.isfinite(self.visible_share)
            else round(self.visible_share, 6),
            "rays_on_box": self.rays_on_box, "split_by_sweep_seam": self.seam,
            "size_lwh_m": self.size.tolist(),
            "world": {"centre": self.centre.tolist(), "heading_rad": self.heading,
                      "origin": self.origin.tolist(),
                      "rotation": self.pose[:3, :3].tolist(),
                      "velocity_mps": self.velocity.tolist()},
            **({} if self.start_matrix is None else {"world_at_sweep_start": self._at_start()}),
            "sensor": {"centre": sensor[:3, 3].tolist(),
                       "heading_rad": float(math.atan2(sensor[1, 0], sensor[0, 0])),
                       "rotation": sensor[:3, :3].tolist(),
                       "velocity_mps": (np.linalg.inv(self.sensor_pose)[:3, :3]
                                        @ self.velocity).tolist()},
        }


def _box_at(box, matrix):
    """The box of ``box``'s object placed by another matrix of the object (the same
    local box: the size and the offset of its centre from the origin are the object's)."""
    rot, _ = polar(np.asarray(matrix, np.float64)[None, :3, :3])
    local = box.pose[:3, :3].T @ (box.pose[:3, 3] - box.origin)  # centre from origin
    origin = np.asarray(matrix, np.float64)[:3, 3]
    return origin + rot[0] @ local, rot[0], origin


def box_frame(matrix, lo, hi):
    """(4x4 box frame -> world, (3,) size) of local box [lo, hi] under object matrix
    ``matrix`` (scale and shear go into the size: each axis' stretch, the rotation of
    the polar decomposition)."""
    m = np.asarray(matrix, np.float64)
    rot, _ = polar(m[None, :3, :3])
    pose = np.eye(4)
    pose[:3, :3] = rot[0]
    pose[:3, 3] = m[:3, :3] @ ((np.asarray(lo) + np.asarray(hi)) / 2) + m[:3, 3]
    size = np.abs(np.asarray(hi) - np.asarray(lo)) * np.linalg.norm(m[:3, :3], axis=0)
    return pose, size


def object_boxes(instances, objects, tracks, classes, result, sensor_pose_at, rmax,
                 noise_sigma=0.0, period=None):
    """Ground-truth boxes of one scan (see the module docstring).

    instances       [Instance] the scene read of this scan
    objects         [ObjectInfo] per instance (stable ids)
    tracks          {instance index: Track} of the objects that moved in this sweep
    classes         label ids that are objects
    result          the ScanResult, scanned with keep_rays=True
    sensor_pose_at  f(times (N,)) -> (N, 4, 4) sensor poses
    rmax            the sensor's range (m)
    period          the sweep period (s), to tell an object on the sweep's seam
    Returns [ObjectBox], by instance id."""
    rays, pts = result.rays_cast, result.points
    classes = set(int(c) for c in classes)
    real = pts["ghost"] == 0
    world = rays.point_world(pts["range"])
    names = {o.name: j for j, o in enumerate(rays.objects)}
    margin = 3.0 * float(noise_sigma) + BOX_MARGIN_M
    if not any(inst.label in classes and len(inst.vertices) for inst in instances):
        return []
    fan = RayFan(rays, world)  # each box looks only at the rays and points toward it
    # each object's own points: the points grouped by instance id once
    by_id = np.argsort(pts["instance"], kind="stable")
    ids = pts["instance"][by_id]
    out = []
    for k, inst in enumerate(instances):
        if inst.label not in classes or not len(inst.vertices):
            continue
        track = tracks.get(k) or Track.fixed(inst.matrix)
        lo, hi = inst.vertices.min(0), inst.vertices.max(0)
        iid = objects[k].instance
        own = by_id[np.searchsorted(ids, iid, "left"):np.searchsorted(ids, iid, "right")]
        own = own[real[own]]
        seam = False
        if len(own):
            t_ref, seam = split_at_seam(pts["time"][own], period)
        else:
            t_ref = _time_facing(rays, track, (lo + hi) / 2, fan)
        matrix = track.at([t_ref])[0]
        pose, size = box_frame(matrix, lo, hi)
        box = ObjectBox(iid, inst.key, inst.label, size, pose, t_ref,
                        _velocity(track, (lo + hi) / 2, t_ref), None, matrix[:3, 3].copy())
        box.points, box.seam = int(len(own)), seam
        box.start_matrix = matrix if t_ref == 0.0 else track.at([0.0])[0]
        near = fan.points_near(pose[:3, 3], float(np.linalg.norm(size / 2 + margin)))
        box.points_in_box = int(np.count_nonzero(real[near] & _inside(world[near], pose, size,
                                                                      margin)))
        box.visible_share, box.rays_on_box = _visibility(rays, names.get(inst.key, -2), pose,
                                                          size, rmax, fan)
        out.append(box)
    if out:  # the sensor's pose at every box's time, in one evaluation
        for box, pose in zip(out, sensor_pose_at(np.array([b.time for b in out]))):
            box.sensor_pose = pose
    return sorted(out, key=lambda b: b.instance)


def split_at_seam(times, period):
    """(reference time, on the seam) of an object's point times. A spinning sensor that
    sees an object across the azimuth where its sweep starts scans one part of it at
    the start of the sweep and the rest at the end, a period apart: two clusters that
    no single box holds when the object moves. Then the box follows the larger one."""
    t = np.asarray(times, np.float64)
    if period and len(t) > 1 and t.max() - t.min() > period / 2:
        early = t < period / 2
        part = t[early] if np.count_nonzero(early) * 2 >= len(t) else t[~early]
        return float(np.median(part)), True
    return float(np.median(t)), False


def _inside(points, pose, size, margin):
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    return np.all(np.abs(local) <= size / 2 + margin, axis=1)


def _velocity(track, centre_local, t, h=1e-3):
    if track.is_static or len(track.times) < 2:
        return np.zeros(3)
    a = max(float(track.times[0]), t - h)
    b = min(float(track.times[-1]), t + h)
    if b <= a:
        return np.zeros(3)
    p = np.c_[np.asarray(centre_local, np.float64)[None], 1.0]
    m = track.at([a, b])
    c = np.einsum("kij,j->ki", m[:, :3, :], p[0])
    return (c[1] - c[0]) / (b - a)


def _time_facing(rays, track, centre_local, fan=None, rounds=2):
    """The firing time of the ray that points most nearly at the object's centre (the
    centre taken at that time again, ``rounds`` times). With a ``RayFan``, only the rays
    around that direction are compared, in widening cones until the best of them is
    inside the cone (then no ray outside it can be better)."""
    c = np.r_[np.asarray(centre_local, np.float64), 1.0]
    t = float(rays.times[0]) if len(rays.times) else 0.0
    for _ in range(rounds):
        centre = (track.at([t])[0] @ c)[:3]
        if not len(rays.dirs):
            break
        best = fan.facing(centre) if fan is not None else None
        if best is None:
            best = _facing(rays, centre, slice(None))[0]
        t = float(rays.times[best])
    return t


def _facing(rays, centre, idx):
    """Index (into all rays) of the ray among ``idx`` that points most nearly at
    ``centre`` from its own origin, and the cosine of its angle."""
    dirs = rays.dirs[idx]
    to = centre - (rays.origins if rays.origins.shape[0] == 1 else rays.origins[idx])
    to /= np.maximum(np.linalg.norm(to, axis=1, keepdims=True), 1e-12)
    dots = np.einsum("ij,ij->i", np.broadcast_to(to, dirs.shape), dirs)
    k = int(np.argmax(dots))
    return (k if isinstance(idx, slice) else int(idx[k])), float(dots[k])


class RayFan:
    """A scan's rays and points ordered by azimuth seen from the sensor, so that a box
    looks only at those toward it. Exact: a direction within angle a of a direction of
    elevation e lies within asin(sin a / cos e) of its azimuth (the longitude span of a
    spherical cap that holds no pole); a moving sensor's rays leave from origins up to
    ``travel`` metres from the first, which widens a cone by asin(travel / distance).
    Where a cone would hold a pole, or the sensor is inside the sphere, every ray is
    taken."""

    def __init__(self, rays, points_world):
        self.rays = rays
        o = np.asarray(rays.origins, np.float64)
        self.o0 = o[0] if len(o) else np.zeros(3)
        self.travel = float(np.linalg.norm(o - self.o0, axis=1).max()) if len(o) > 1 else 0.0
        self._dirs = _AzimuthOrder(rays.dirs)
        self._points = _AzimuthOrder(np.asarray(points_world, np.float64) - self.o0)

    def _cone(self, centre, radius, extra):
        """Half-angle of the cone from o0 holding every ray that passes within
        ``radius`` of ``centre`` (``extra`` m of origin travel), or None: all."""
        v = np.asarray(centre, np.float64) - self.o0
        dist = float(np.linalg.norm(v))
        reach = radius + extra
        if dist <= reach:
            return v, None
        return v, math.asin(reach / dist)

    def rays_near(self, centre, radius):
        """Sorted indices of the rays that may pass within ``radius`` of ``centre``."""
        v, angle = self._cone(centre, radius, self.travel)
        return self._dirs.within(v, angle)

    def points_near(self, centre, radius):
        """Sorted indices of the points that may lie within ``radius`` of ``centre``."""
        v, angle = self._cone(centre, radius, 0.0)
        return self._points.within(v, angle)

    def facing(self, centre):
        """Index of the ray pointing most nearly at ``centre`` from its own origin (as
        ``_facing`` over all rays), or None when no cone settles it."""
        v = np.asarray(centre, np.float64) - self.o0
        dist = float(np.linalg.norm(v))
        if dist <= self.travel + 1e-9:
            return None
        drift = math.asin(min(1.0, self.travel / dist))
        angle = 0.02
        while angle + drift < math.pi / 4:
            idx = self._dirs.within(v, angle + drift)
            if len(idx):
                k, cos = _facing(self.rays, centre, idx)
                # the best ray in the cone is within ``angle`` of the centre: any better
                # ray is closer still, so inside the cone too
                if cos >= math.cos(angle):
                    return k
            angle *= 4.0
        return None


class _AzimuthOrder:
    """Vectors grouped by azimuth (atan2(y, x)) in ``BINS`` sectors, to take those within
    a cone quickly (the sectors a cone's span touches: a superset). A radix sort of the
    sector numbers, not a sort of the angles: a sixth of the time on a Pandar64 frame."""

    BINS = 1440  # quarter-degree sectors

    def __init__(self, vectors):
        v = np.asarray(vectors, np.float64).reshape(-1, 3)
        self.n = len(v)
        az = np.arctan2(v[:, 1], v[:, 0])
        sector = np.floor((az + math.pi) * (self.BINS / (2 * math.pi))).astype(np.int16)
        np.clip(sector, 0, self.BINS - 1, out=sector)  # +pi falls in the last one
        self.order = np.argsort(sector, kind="stable")
        self.starts = np.zeros(self.BINS + 1, np.int64)
        np.cumsum(np.bincount(sector, minlength=self.BINS), out=self.starts[1:])

    def _sectors(self, lo, hi):
        scale = self.BINS / (2 * math.pi)
        a = max(0, int(math.floor((lo + math.pi) * scale)))
        b = min(self.BINS - 1, int(math.floor((hi + math.pi) * scale)))
        return self.order[self.starts[a]:self.starts[b + 1]]

    def within(self, v, angle):
        """Sorted indices of the vectors that may lie within ``angle`` of direction
        ``v`` (by azimuth: a superset); all of them when ``angle`` is None or the cone
        holds a pole."""
        every = np.arange(self.n)
        h = math.hypot(float(v[0]), float(v[1]))
        if angle is None or h == 0.0:
            return every
        elevation = math.atan2(abs(float(v[2])), h)
        if angle >= math.pi / 2 - elevation:
            return every
        span = math.asin(min(1.0, math.sin(angle) / math.cos(elevation))) + 1e-9
        a = math.atan2(float(v[1]), float(v[0]))
        lo, hi = a - span, a + span
        parts = [(lo, hi)]
        if lo < -math.pi:
            parts = [(-math.pi, hi), (lo + 2 * math.pi, math.pi)]
        elif hi > math.pi:
            parts = [(lo, math.pi), (-math.pi, hi - 2 * math.pi)]
        return np.sort(np.concatenate([self._sectors(p, q) for p, q in parts]))


def _visibility(rays, obj, pose, size, rmax, fan=None):
    """(share of the box's silhouette rays that reach object ``obj``, rays on the box)."""
    # Only rays that pass the box's bounding sphere are tested against the box (and
    # with a ``RayFan``, only those toward it are tested against the sphere).
    radius = float(np.linalg.norm(size)) / 2 + 1e-6
    cand = fan.rays_near(pose[:3, 3], radius) if fan is not None else slice(None)
    origins = rays.origins if rays.origins.shape[0] == 1 else rays.origins[cand]
    near = np.nonzero(ray_meets_sphere(origins, rays.dirs[cand], pose[:3, 3], radius, rmax))[0]
    if not isinstance(cand, slice):
        near = cand[near]
    r = pose[:3, :3]
    origins = rays.origins if rays.origins.shape[0] == 1 else rays.origins[near]
    o = (origins - pose[:3, 3]) @ r
    d = rays.dirs[near] @ r
    half = size / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (-half - o) * inv
        t2 = (half - o) * inv
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    t_in = np.minimum(t1, t2).max(axis=1)
    t_out = np.maximum(t1, t2).min(axis=1)
    on = (t_in <= t_out) & (t_out > 0) & (t_in <= rmax)
    hit, dist = rays.object[near], rays.dist[near]
    seen = on & (hit == obj)
    blocked = on & ~seen & (hit >= 0) & (dist < np.maximum(t_in, 0) + 1e-6)
    n_seen, n_blocked = int(np.count_nonzero(seen)), int(np.count_nonzero(blocked))
    total = n_seen + n_blocked
    return (n_seen / total if total else math.nan), total
