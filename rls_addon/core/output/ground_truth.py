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

A frame's boxes are made all at once (``object_boxes``): the objects' poses from one
evaluation of every track (``scene.track_set``), the rays and points near each box
from the rays grouped once by direction (``ray_cells``), every box's counts in one
pass (``box_counts``, compiled where built), every box's own points grouped in one
pass over the point records (``box_counts.own_groups``, compiled where built).
``box_reference`` makes them box by box, as this module did before (about 95 ms of a
230 ms frame through the sample intersection's traffic, 2026-11-28); the tests hold
the two to the same numbers.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..labels import label_name
from ..scene.motion import polar
from ..scene.track_set import TrackSet
from . import box_counts
from .ray_cells import RayCells

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

    def _at_start(self, rot=None):
        """Where the box was at the sweep start (the time of the sidecar's
        ``sensor_pose_start``): what a simulator's per-tick poses give, e.g. OPV2V's
        ``true_ego_pos`` beside its ``lidar_pose``. ``rot``: the start matrix's
        rotation when already decomposed."""
        centre, rot, origin = _box_at(self, self.start_matrix, rot)
        return {"centre": centre.tolist(), "origin": origin.tolist(), "rotation": rot.tolist(),
                "heading_rad": float(math.atan2(rot[1, 0], rot[0, 0]))}

    def to_dict(self):
        inv = np.linalg.inv(self.sensor_pose)
        return self._dict(inv, self.in_frame(inv), None)

    def _dict(self, inv_sensor, sensor, start_rot):
        """``to_dict`` from the sensor pose's inverse, the box in the sensor frame and
        the start matrix's rotation (None: decomposed here)."""
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
            **({} if self.start_matrix is None
               else {"world_at_sweep_start": self._at_start(start_rot)}),
            "sensor": {"centre": sensor[:3, 3].tolist(),
                       "heading_rad": float(math.atan2(sensor[1, 0], sensor[0, 0])),
                       "rotation": sensor[:3, :3].tolist(),
                       "velocity_mps": (inv_sensor[:3, :3] @ self.velocity).tolist()},
        }


def box_dicts(boxes):
    """``[b.to_dict() for b in boxes]``, the same dicts: the sensor poses' inverses, the
    boxes in the sensor frame and the start matrices' rotations made for all boxes at
    once (one decomposition per matrix, one product per box, as box by box)."""
    if not boxes:
        return []
    inv = np.linalg.inv(np.array([b.sensor_pose for b in boxes], np.float64))
    sensor = inv @ np.array([b.pose for b in boxes], np.float64)
    starts = [j for j, b in enumerate(boxes) if b.start_matrix is not None]
    rots = [None] * len(boxes)
    if starts:
        got, _ = polar(np.array([boxes[j].start_matrix for j in starts], np.float64)[:, :3, :3])
        for j, r in zip(starts, got):
            rots[j] = r
    return [b._dict(inv[j], sensor[j], rots[j]) for j, b in enumerate(boxes)]


def _box_at(box, matrix, rot=None):
    """The box of ``box``'s object placed by another matrix of the object (the same
    local box: the size and the offset of its centre from the origin are the object's);
    ``rot``: the matrix's rotation (``polar``) when already worked out."""
    if rot is None:
        rot = polar(np.asarray(matrix, np.float64)[None, :3, :3])[0][0]
    local = box.pose[:3, :3].T @ (box.pose[:3, 3] - box.origin)  # centre from origin
    origin = np.asarray(matrix, np.float64)[:3, 3]
    return origin + rot @ local, rot, origin


def box_frames(matrices, lo, hi):
    """``box_frame`` of many boxes at once ((N, 4, 4) matrices, (N, 3) corners): the
    same numbers (one decomposition per matrix, one product per box)."""
    m = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    rot, _ = polar(m[:, :3, :3])
    poses = np.zeros((len(m), 4, 4))
    poses[:] = np.eye(4)
    poses[:, :3, :3] = rot
    mid = (np.asarray(lo) + np.asarray(hi)) / 2
    poses[:, :3, 3] = np.matmul(m[:, :3, :3], mid[:, :, None])[:, :, 0] + m[:, :3, 3]
    sizes = np.abs(np.asarray(hi) - np.asarray(lo)) * np.linalg.norm(m[:, :3, :3], axis=1)
    return poses, sizes


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
    """Ground-truth boxes of one scan (see the module docstring), every box at once:
    the objects' poses from one evaluation of all their tracks (``TrackSet``), the
    rays and points near each box from the rays grouped once by direction
    (``RayCells``) and every box's counts over them in one pass (``box_counts``); box
    for box what ``box_reference.object_boxes_per_object`` gives (tested).

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
    chosen = [k for k, inst in enumerate(instances)
              if inst.label in classes and len(inst.vertices)]
    if not chosen:
        return []
    n = len(chosen)
    tset = TrackSet.of([tracks.get(k) for k in chosen], [instances[k].matrix for k in chosen])
    lo = np.array([instances[k].vertices.min(0) for k in chosen])
    hi = np.array([instances[k].vertices.max(0) for k in chosen])
    ids = np.array([objects[k].instance for k in chosen], np.int64)
    cells = RayCells(rays)
    own, times, seams = _own_points(pts, ids, period)
    blind = [j for j in range(n) if times[j] is None]  # returned no point
    for j, t in zip(blind, _times_facing(cells, tset, blind, (lo + hi) / 2)):
        times[j] = t
    t_ref = np.array(times, np.float64)
    every = np.arange(n)
    spans = [_velocity_span(tr, t) for tr, t in zip(tset.tracks, t_ref)]
    moving = [j for j in range(n) if spans[j] is not None]
    # every track at once: at the reference times, at the sweep start, and around the
    # reference times for the velocities
    at = tset.at(np.r_[every, every, np.repeat(moving, 2)].astype(np.int64),
                 np.r_[t_ref, np.zeros(n), np.array([spans[j] for j in moving]).reshape(-1)])
    matrices, starts, ab = at[:n], at[n:2 * n], at[2 * n:]
    poses, sizes = box_frames(matrices, lo, hi)
    margin = 3.0 * float(noise_sigma) + BOX_MARGIN_M
    # the rays toward each box, out to the larger of its two spheres (its points' and
    # its silhouette's), hold what both counts need
    radii = np.maximum(np.linalg.norm(sizes / 2 + margin, axis=1),
                       np.linalg.norm(sizes, axis=1) / 2 + 1e-6)
    # and each box grown by its margin, as half sizes along the world's axes (its
    # rotated half sizes' absolute sums): what narrows a sphere holding the sensor
    extents = np.einsum("bij,bj->bi", np.abs(poses[:, :3, :3]),
                        sizes / 2 + max(margin, 0.0)) * (1 + 1e-9)
    names = {o.name: j for j, o in enumerate(rays.objects)}
    share, on_box, inside = box_counts.box_counts(
        cells, [names.get(instances[k].key, -2) for k in chosen], poses, sizes, margin, rmax,
        pts["range"], pts["ghost"] == 0, cells.segments(poses[:, :3, 3], radii, extents))
    sensor = sensor_pose_at(t_ref)
    velocities = np.zeros((n, 3))
    if moving:
        velocities[moving] = _velocities_from(ab.reshape(-1, 2, 4, 4), ((lo + hi) / 2)[moving],
                                              np.array([spans[j] for j in moving]))
    out = []
    for j, k in enumerate(chosen):
        inst = instances[k]
        b = ObjectBox(int(ids[j]), inst.key, inst.label, sizes[j], poses[j], float(t_ref[j]),
                      velocities[j], sensor[j], matrices[j, :3, 3].copy())
        b.points, b.seam = int(own[j]), seams[j]
        b.start_matrix = matrices[j] if t_ref[j] == 0.0 else starts[j]
        b.points_in_box = int(inside[j])
        b.visible_share, b.rays_on_box = float(share[j]), int(on_box[j])
        out.append(b)
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


def _own_points(pts, ids, period):
    """Per box (instance ids ``ids``): how many real (not ghost) points carry its id,
    and its reference time and seam flag from their times (``split_at_seam``; None
    for a box with no point). The points are grouped by box once (those whose id is a
    box's, in their order) and every group's median and seam test are read off the
    groups' times sorted once (``_medians``)."""
    n = len(ids)
    times, seams = [None] * n, [False] * n
    unique, box_of = np.unique(ids, return_inverse=True)
    got = None
    if unique[0] >= 0 and unique[-1] <= np.iinfo(np.uint32).max:
        got = box_counts.own_groups(pts, unique)  # compiled, where built
    first, t = got if got is not None else _own_groups_numpy(pts, unique)
    count = (first[1:] - first[:-1])[box_of]
    got = _medians(t, first, period)
    if got is None:  # not finite: box by box
        got = [split_at_seam(t[first[u]:first[u + 1]], period) if first[u + 1] > first[u]
               else (None, False) for u in range(len(unique))]
    for j in range(n):
        if count[j]:
            times[j], seams[j] = got[box_of[j]]
    return count, times, seams


def _own_groups_numpy(pts, unique):
    """The real (not ghost) points whose id is one of ``unique`` (sorted) grouped by
    it: (the groups' starts, len(unique) + 1; the groups' times, each group in the
    points' order). The reference of the compiled ``box_counts.own_groups``."""
    inst = np.ascontiguousarray(pts["instance"])
    if inst.dtype != np.uint32 or unique[0] < 0 or unique[-1] > np.iinfo(np.uint32).max:
        inst = inst.astype(np.int64)
    keys = unique.astype(inst.dtype)  # the points' own type: no search converts them
    pos = np.minimum(np.searchsorted(keys, inst), len(unique) - 1)
    rows = np.nonzero((keys[pos] == inst) & (pts["ghost"] == 0))[0]
    group = pos[rows]
    # a radix sort of small keys
    order = np.argsort(group.astype(np.int16 if len(unique) < 2 ** 15 else np.int64),
                       kind="stable")
    rows = rows[order]
    first = np.searchsorted(group[order], np.arange(len(unique) + 1))
    return first, np.asarray(pts["time"], np.float64)[rows]


def _medians(t, first, period):
    """``split_at_seam`` of every group of times ``t[first[u]:first[u + 1]]`` at once:
    [(median, seam)] per group (None, False for an empty one), the same numbers
    (numpy's median: the middle time, or half the sum of the middle two). The times
    are sorted within their groups once (already so when the points come in firing
    order, as a scan gives them); None when a time is not finite (then box by box)."""
    if not np.all(np.isfinite(t)):
        return None
    sizes = first[1:] - first[:-1]
    groups = np.repeat(np.arange(len(sizes)), sizes)
    if len(t) > 1 and not np.all((t[1:] >= t[:-1]) | (groups[1:] != groups[:-1])):
        t = t[np.lexsort((t, groups))]
    lo, hi = first[:-1].copy(), first[1:].copy()
    seam = np.zeros(len(sizes), bool)
    if period:
        span = np.where(sizes > 1, t[np.maximum(hi - 1, 0)] - t[np.minimum(lo, len(t) - 1)],
                        0.0) if len(t) else np.zeros(len(sizes))
        seam = (sizes > 1) & (span > period / 2)
        # the early times (t < period / 2) open each group: the larger part is kept
        cut = np.array([lo[u] + int(np.searchsorted(t[lo[u]:hi[u]], period / 2, "left"))
                        for u in np.nonzero(seam)[0]], np.int64)
        s = np.nonzero(seam)[0]
        early = (cut - lo[s]) * 2 >= sizes[s]
        hi[s] = np.where(early, cut, hi[s])
        lo[s] = np.where(early, lo[s], cut)
    out = []
    for u in range(len(sizes)):
        m = int(hi[u] - lo[u])
        if not sizes[u]:
            out.append((None, False))
            continue
        mid = int(lo[u]) + m // 2
        median = t[mid] if m % 2 else (t[mid - 1] + t[mid]) / 2
        out.append((float(median), bool(seam[u])))
    return out


def _times_facing(cells, tset, boxes, centres_local, rounds=2):
    """The reference times of the boxes ``boxes`` (indices into ``tset``) whose
    objects returned nothing: the firing time of the ray that points most nearly at
    the object's centre, the centre taken at that time again, ``rounds`` times
    (``box_reference._time_facing``, every box's track evaluated at once). A box whose
    centre a round leaves where it was (an object that stood still) keeps its ray:
    the same centre faces the same ray (``facing_rays`` answers each centre on its
    own), so it is not looked for again."""
    rays = cells.rays
    t = np.full(len(boxes), float(rays.times[0]) if len(rays.times) else 0.0)
    if not len(boxes):
        return t
    local = [np.r_[np.asarray(centres_local[j], np.float64), 1.0] for j in boxes]
    last = None
    for _ in range(rounds):
        at = tset.at(boxes, t)
        if not len(rays.dirs):
            break
        centres = np.array([(at[q] @ c)[:3] for q, c in enumerate(local)])
        moved = np.arange(len(boxes)) if last is None else \
            np.nonzero((centres != last).any(axis=1))[0]
        last = centres
        if not len(moved):
            break
        best = box_counts.facing_rays(cells, centres[moved])
        for q in np.nonzero(best < 0)[0]:
            best[q] = box_counts.facing(rays, centres[moved[q]], slice(None))[0]
        t[moved] = np.asarray(rays.times, np.float64)[best]
    return t


def _velocity_span(track, t, h=1e-3):
    """The times (a, b) around ``t`` whose positions give a velocity by their
    difference, within the track's span; None for a track that does not move."""
    if track.is_static or len(track.times) < 2:
        return None
    a = max(float(track.times[0]), t - h)
    b = min(float(track.times[-1]), t + h)
    return None if b <= a else (a, b)


def _velocity_from(m, centre_local, a, b):
    """The velocity of a local point from the object's matrices ``m`` (2, 4, 4) at
    times a and b."""
    p = np.c_[np.asarray(centre_local, np.float64)[None], 1.0]
    c = np.einsum("kij,j->ki", m[:, :3, :], p[0])
    return (c[1] - c[0]) / (b - a)


def _velocities_from(m, centres_local, spans):
    """``_velocity_from`` of many objects at once: matrices ``m`` (N, 2, 4, 4) at the
    times ``spans`` (N, 2), local points ``centres_local`` (N, 3); the same sums in the
    same order (each row's four products added left to right)."""
    p = np.c_[np.asarray(centres_local, np.float64), np.ones(len(m))]
    c = np.einsum("nkij,nj->nki", m[:, :, :3, :], p)
    return (c[:, 1] - c[:, 0]) / (spans[:, 1] - spans[:, 0])[:, None]


def _velocity(track, centre_local, t, h=1e-3):
    span = _velocity_span(track, t, h)
    if span is None:
        return np.zeros(3)
    return _velocity_from(track.at(list(span)), centre_local, *span)
