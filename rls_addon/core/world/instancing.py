"""One traversal for the static scene and every rigidly moving object (Embree).

``RigidBodies.cast`` carries each (ray, object) pair into the object's frame in numpy:
portable, exact, and costly once there are many objects (ten cars cost more than the
whole static street). With the Embree backend and its compiled loop the world is
traced instead as Embree instances in one top-level scene: the static scene placed
as it is, every moving object placed by its track sampled at evenly spaced time steps
over the sweep, each ray carrying its own time. Embree interpolates an object's
matrix linearly between steps, bounds its motion and finds the nearest hit over
everything at once.

Embree only decides *what* a ray hits. The compiled loop then refines every hit in
float64: static hits against their plane as always (``casting.cast_exact``), hits on
a moving object against its triangle's plane in the object's own coordinates, with
the object's matrix interpolated at the ray's own time. The steps are dense enough
that this interpolated pose stays within ``STEP_TOLERANCE_M`` of the track (two
steps are exact for a car driving straight), so ranges match ``RigidBodies`` to a
hundredth of a millimetre. An object whose track Embree's most steps
(``MAX_STEPS``) cannot follow that closely (it jumps, or turns sharply, within the
sweep) is not an instance: it is cast the portable way (``RigidBodies.cast`` of that
object alone, exact at every ray's time) and its hits merged in (``portable``).
"""

import numpy as np

from ..native.vectors import shifted
from ..scene.geometry import hit_body
from ..scene.track_set import TrackSet

STEP_TOLERANCE_M = 1e-5  # steps: linear interpolation within 10 um of the track
MAX_STEPS = 129          # Embree's limit (RTC_MAX_TIME_STEP_COUNT)
# a box's eight corners: which of (min, max) each coordinate takes, in the order of
# np.meshgrid(*zip(min, max), indexing="ij")
_CORNER_BITS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], bool)


class InstancedWorld:
    """The static ``PreparedScene`` and ``RigidBodies`` of one sweep as one Embree
    scene (see the module docstring); build with ``InstancedWorld.build``."""

    def __init__(self, static, rigid, instances_cls, with_static=True):
        self.static = static
        self.centre = static.centre
        primary = static.primary
        placed, self.parts = [], []
        self.portable = {}  # world body index -> its objects cast the portable way
        self.first = 0
        if primary is not None and with_static:
            placed.append((primary, np.eye(4), static.planes))
            self.first = 1
        tracks = [tr for _, rb in rigid for tr in rb.tracks]
        moving = [tr for tr in tracks if len(tr.times) > 1 and not tr.is_static]
        self.t0 = min((float(tr.times[0]) for tr in moving), default=0.0)
        self.t1 = max((float(tr.times[-1]) for tr in moving), default=0.0)
        self.moving = self.t1 > self.t0
        todo = []  # objects whose steps this sweep has not worked out yet: all at once
        for body, rb in rigid:
            casters = rb.local_casters()
            for k, track in enumerate(rb.tracks):
                key = (k, self.t0, self.t1, tuple(self.centre))
                if casters[k] is not None and key not in rb.derived:
                    todo.append((rb, key, track, rb.centres[k], rb.local[k][0]))
        for (rb, key, *_), got in zip(todo, self._steps_many([t[2:] for t in todo])):
            rb.derived[key] = got
        for body, rb in rigid:
            casters = rb.local_casters()
            for k, track in enumerate(rb.tracks):
                if casters[k] is None:
                    continue
                caster, planes = casters[k]
                mats, close = rb.derived[(k, self.t0, self.t1, tuple(self.centre))]
                if not close:
                    # Motion Embree's steps cannot follow within the tolerance: this
                    # object is cast on its own, exactly (World.start merges it in).
                    self.portable.setdefault(body, []).append(k)
                    continue
                placed.append((caster, mats, planes))
                self.parts.append((body, rb, k))
        self.instances = instances_cls(placed) if placed else None
        # world body indices traced here (their objects in ``portable`` excepted)
        self.traced = {body for body, _ in rigid}
        self._part_body = np.array([b for b, _, _ in self.parts], np.int64)
        self._part_tri_start = np.array([rb.tri_start[k] for _, rb, k in self.parts], np.int64)

    @classmethod
    def build(cls, static, moving, with_static=True):
        """An ``InstancedWorld`` for ``static`` and the ``RigidBodies`` among
        ``moving`` (world body index = position in ``moving`` + 1), or None when the
        backend cannot instance (then each body casts on its own). ``with_static=False``
        leaves the static scene out (its cast is reused from an earlier frame, see
        ``PreparedScene.cast``): only the moving objects are traced. The last one built
        each way for ``static`` is kept and reused while the bodies and their tracks are
        the same objects (frames of a sweep scanned again, several sensors)."""
        from .bodies import RigidBodies

        rigid = [(k, b) for k, b in enumerate(moving, start=1) if isinstance(b, RigidBodies)]
        if not rigid:
            return None
        key = [(k, b, tuple(b.tracks)) for k, b in rigid]
        built_for = static.instanced_cache
        last = built_for.get(with_static)
        if last is not None and _same(last[0], key):
            return last[1]
        built = cls._build(static, rigid, with_static)
        built_for[with_static] = (key, built)
        return built

    @classmethod
    def _build(cls, static, rigid, with_static=True):
        factory = rigid[0][1].factory
        instances_cls = factory.instances
        if instances_cls is None or any(b.factory is not factory for _, b in rigid):
            return None
        primary = static.primary
        if primary is not None and not instances_cls.usable(primary):
            return None
        for _, b in rigid:
            if not all(c is None or instances_cls.usable(c[0]) for c in b.local_casters()):
                return None
        built = cls(static, rigid, instances_cls, with_static)
        return built if built.instances is not None else None  # nothing left to instance

    def _steps(self, track, centre, local_vertices):
        """((S, 4, 4) matrices from the object's centred coordinates to the static
        scene's centre-relative frame at S evenly spaced times over [t0, t1], whether
        they follow the track within STEP_TOLERANCE_M): S starts at four steps per
        segment of the track and is doubled until linear interpolation between steps
        stays that close to the track at the middle of every step (on the object's
        bounding box); never more than Embree's limit, ``MAX_STEPS``. The reference of
        ``_steps_many``, one object at a time."""
        return self._steps_many([(track, centre, local_vertices)], each=True)[0]

    def _steps_many(self, objects, each=False):
        """``_steps`` of every object of [(track, centre, local vertices)], the tracks
        of a round evaluated together (``TrackSet``) and the objects with as many
        steps checked as one array (``each``: track by track, the reference): the same
        matrices, byte for byte, for a fraction of the cost."""
        out = [None] * len(objects)
        tracks = TrackSet([tr for tr, _, _ in objects]) if objects and not each else None
        steps, corners, shifts = {}, {}, {}
        for j, (track, centre, local_vertices) in enumerate(objects):
            shift = shifts[j] = np.eye(4)
            shift[:3, 3] = centre
            if not self.moving or len(track.times) < 2 or track.is_static:
                m = track.at([track.times[0]])[0] @ shift
                m[:3, 3] -= self.centre
                out[j] = (m[None], True)
                continue
            # its bounding box's corners, in meshgrid's "ij" order
            corners[j] = np.where(_CORNER_BITS, local_vertices.max(0), local_vertices.min(0))
            steps[j] = 2 if len(track.times) == 2 else min(4 * (len(track.times) - 1) + 1,
                                                            MAX_STEPS)
        while steps:
            if each:  # the reference: object by object, track by track
                for j in list(steps):
                    t = np.linspace(self.t0, self.t1, steps[j])
                    track = objects[j][0]
                    m, mid = track.at(t) @ shifts[j], track.at((t[1:] + t[:-1]) / 2) @ shifts[j]
                    lerp = (m[1:] + m[:-1]) / 2
                    dev = np.einsum("kij,cj->kci", (mid - lerp)[:, :3, :3], corners[j]) \
                        + (mid - lerp)[:, None, :3, 3]
                    close = np.linalg.norm(dev, axis=2).max() <= STEP_TOLERANCE_M
                    if close or steps[j] >= MAX_STEPS:
                        m[:, :3, 3] -= self.centre
                        out[j] = (m, bool(close))
                        del steps[j]
                    else:
                        steps[j] = min(2 * steps[j] - 1, MAX_STEPS)
                continue
            # the objects of each step count at once: times, tracks, matrices, checks
            groups = {}
            for j, n in steps.items():
                groups.setdefault(n, []).append(j)
            which, when = [], []
            for n, js in groups.items():
                t = np.linspace(self.t0, self.t1, n)
                rows = np.r_[t, (t[1:] + t[:-1]) / 2]
                which.append(np.repeat(js, len(rows)))
                when.append(np.tile(rows, len(js)))
            got = tracks.at(np.concatenate(which), np.concatenate(when))
            first = 0
            for n, js in groups.items():
                block = got[first:first + len(js) * (2 * n - 1)].reshape(len(js), 2 * n - 1,
                                                                         4, 4)
                first += len(js) * (2 * n - 1)
                shift = np.stack([shifts[j] for j in js])[:, None]
                self._round(steps, out, js, block[:, :n] @ shift, block[:, n:] @ shift,
                            np.stack([corners[j] for j in js]))
        return out

    def _round(self, steps, out, js, m, mid, corners):
        """One round of ``_steps_many`` for the objects ``js`` of one step count: their
        matrices at the steps ``m`` (J, S, 4, 4) and at the steps' middles ``mid``
        (J, S - 1, 4, 4), their bounding boxes' ``corners`` (J, 8, 3). An object whose
        linear interpolation stays within the tolerance (or that has Embree's most
        steps) is done, the others double their steps."""
        lerp = (m[:, 1:] + m[:, :-1]) / 2
        gap = mid - lerp
        # (J, S - 1, 3, 8): each corner's deviation, the rotation part as a product
        dev = gap[:, :, :3, :3] @ np.swapaxes(corners, 1, 2)[:, None] + gap[:, :, :3, 3:]
        worst = np.sqrt((dev * dev).sum(axis=2)).reshape(len(js), -1).max(axis=1)
        for q, j in enumerate(js):
            close = worst[q] <= STEP_TOLERANCE_M
            if close or steps[j] >= MAX_STEPS:
                got = m[q].copy()
                got[:, :3, 3] -= self.centre
                out[j] = (got, bool(close))
                del steps[j]
            else:
                steps[j] = min(2 * steps[j] - 1, MAX_STEPS)

    def start(self, origins, directions, times, max_range, order=None, watertight=True):
        """Start the cast; returns a function giving (dist, body, tri, normals) as
        ``World.cast`` does (``tri`` indexes the body's geometry)."""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64)
        t = np.asarray(times, np.float64)
        tau = np.clip((t - self.t0) / (self.t1 - self.t0), 0.0, 1.0) if self.moving else None
        oc = shifted(o, self.centre)  # read-only: its bounds are kept (column_bounds)
        recheck = None
        if self.first and watertight and self.static.watertight:
            # the static scene's re-check in the loop's threads, where it is compiled
            recheck = self.static.caster.native_recheck(oc, max_range, self.static.planes,
                                                        limit=True)
        pending = self.instances.start(oc, d, max_range, tau, order, recheck)

        def finish():
            got = pending()
            if recheck is not None:
                self.static.caster.retried += recheck[0].retried
            return self._finish(got, o, d, t, max_range, watertight and recheck is None)

        return finish

    def _finish(self, got, o, d, t, max_range, watertight):
        """The instanced cast's result as the world's: moving hits beyond the range
        dropped, and (``watertight``, when the loop did not) the static scene's
        re-check of the rays that did not hit it, in numpy: the reference of the
        compiled re-check (``WatertightCaster.native_recheck``)."""
        dist, tri, normals, inst = got
        first = self.first
        far = np.nonzero((inst >= first) & ~(dist <= max_range))[0]
        inst[far], dist[far], normals[far] = -1, np.inf, 0.0
        st = np.where(inst == 0, tri, -1) if first else np.full(len(dist), -1, np.int64)
        if first and watertight and self.static.watertight:
            # Misses, and hits on moving objects that a crack in the static scene
            # might hide, are re-checked against the static scene alone.
            sd, sn = dist.copy(), normals.copy()
            sd[inst != 0] = np.inf
            won = self.static.caster.win_back(o - self.centre, d, max_range,
                                              self.static.planes, sd, st, sn, limit=dist)
            closer = sd.take(won) < dist.take(won)
            st[won[~closer]] = -1
            won = won[closer]
            dist[won], normals[won], inst[won] = sd[won], sn[won], 0
        # _to_geometry ends in -1, so misses (-1) map to -1.
        out_tri = self.static._to_geometry[st] if first else st
        body = hit_body(st)
        moved = np.nonzero(inst >= first)[0]
        if len(moved):
            part = inst.take(moved) - first
            body[moved] = self._part_body.take(part)
            out_tri[moved] = self._part_tri_start.take(part) + tri.take(moved)
        return dist, body, out_tri, normals


def _same(a, b):
    """Keys of ``build``'s cache equal, comparing bodies and tracks by identity."""
    return len(a) == len(b) and all(
        ka == kb and ba is bb and len(ta) == len(tb) and all(x is y for x, y in zip(ta, tb))
        for (ka, ba, ta), (kb, bb, tb) in zip(a, b))
