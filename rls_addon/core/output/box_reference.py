"""The ground-truth boxes one object at a time: the reference that
``ground_truth.object_boxes`` (every box in one pass over the rays and points, see
``ray_cells`` and ``box_counts``) is tested against, box for box
(``tests/core/test_boxes_vectorised.py``).

Each box looks only at the rays and points toward it (``RayFan``: the rays and the
points ordered by azimuth seen from the sensor), then counts its points inside it, its
visibility over the rays that cross it, and finds the ray that faces it for an object
that returned nothing.
"""

import math

import numpy as np

from ..world.bodies import ray_meets_sphere
from ..scene.motion import Track
from .box_counts import facing as _facing
from .ground_truth import BOX_MARGIN_M, ObjectBox, _velocity, box_frame, split_at_seam


def object_boxes_per_object(instances, objects, tracks, classes, result, sensor_pose_at, rmax,
                 noise_sigma=0.0, period=None):
    """Ground-truth boxes of one scan, box by box (``ground_truth.object_boxes``'s
    arguments and result).

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


def _inside(points, pose, size, margin):
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    return np.all(np.abs(local) <= size / 2 + margin, axis=1)


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
