"""What a sweep casts into, each prepared once and cast into as needed:

- ``PreparedScene``: static triangles in centre-relative coordinates;
- ``RigidBodies``: moving objects' triangles in their own local coordinates with a
  ``Track`` of each pose over the sweep; every ray is carried into the object's frame
  at the ray's own scene time, so motion is exact with no sub-steps and no rebuilds;
- ``TimedScene``: a deforming object's triangles at one sub-step, valid for rays whose
  scene time falls into that sub-step.

``world.World`` casts into all of them at once.
"""

import math

import numpy as np

from ..casting import WatertightCaster, cast_exact, triangle_planes
from ..native.vectors import column_bounds, shifted
from ..scene.geometry import clean_for_casting, concatenate


def _frozen(a):
    """A read-only array that owns its data: its contents cannot change."""
    return isinstance(a, np.ndarray) and a.base is None and not a.flags.writeable


class PreparedScene:
    """Triangles ready for casting around ``centre``: shifted to centre-relative float64
    coordinates (so scenes far from the origin keep their precision in float32
    backends), degenerate triangles dropped, everything farther than ``reach`` from
    ``centre`` culled, and the caster built once (wrapped so that rays through shared
    edges and vertices never slip through, see ``WatertightCaster``)."""

    reuse_casts = True  # see cast(reuse=True); set False to time cold frames

    def __init__(self, geometry, centre, reach, caster_factory, watertight=True, hull_cell=None):
        self.geometry = geometry
        self.centre = np.asarray(centre, dtype=np.float64).copy()
        self.reach = float(reach)
        self.vertices, self.triangles, self.kept, self.warnings = clean_for_casting(
            geometry, self.centre, self.reach)
        # caster: what casts watertight (the wrapper, or the backend itself when
        # ``watertight`` is off); primary: the backend's own build, for casts that
        # need no re-check (secondary rays, instancing). None with no triangles.
        self.caster = self.primary = None
        self.watertight = bool(watertight)
        if len(self.triangles):
            if watertight:
                self.caster = WatertightCaster(caster_factory, self.vertices, self.triangles,
                                               geometry.tri_object[self.kept], hull_cell)
                self.primary = self.caster.primary
            else:
                self.caster = self.primary = caster_factory(self.vertices, self.triangles)
        self.backend = "none" if self.caster is None else self.caster.name
        self.instanced_cache = {}  # instancing.InstancedWorld.build's, per with_static
        self._joined_table = None  # world.World._joined_table's, for the last bodies
        self.planes = triangle_planes(self.vertices, self.triangles)
        # Caster triangle -> geometry triangle, with a trailing -1 that misses (-1) pick.
        self._to_geometry = np.append(self.kept, -1).astype(np.int64)
        self._kept_cast = None
        self.reused = 0  # casts answered from the kept one

    def covers(self, origin, max_range):
        """True when every ray from ``origin`` (one point or (N, 3)) stays inside the
        culled region."""
        o = np.asarray(origin, np.float64).reshape(-1, 3)
        if len(o) > 1:
            # The farthest corner of the box around the origins first (a driving
            # sensor's origin per ray): no origin's offset from the centre exceeds the
            # corner's along any axis, in floating point too (rounding keeps order), so
            # when the corner is covered every origin is; else each is looked at.
            c = self.centre
            lo, hi = column_bounds(origin)
            far = [max(abs(float(lo[k]) - c[k]), abs(float(hi[k]) - c[k])) for k in range(3)]
            if math.sqrt(far[0] * far[0] + far[1] * far[1] + far[2] * far[2]) + max_range \
                    <= self.reach * (1 + 1e-12):
                return True
        d = o - self.centre
        # column by column: a norm along the rows' three numbers is 8x slower on a
        # driving sensor's origin per ray (the same sums, the same largest distance)
        gap = math.sqrt(float((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]).max()))
        return gap + max_range <= self.reach * (1 + 1e-12)

    def reusable(self, origins, directions):
        """True when ``cast(..., reuse=True)`` may keep or reuse a cast of these rays:
        one origin (or one per ray in a read-only array that owns its data: what
        ``ScanPattern.placed_origins`` gives beams with their own origins), and
        directions in a read-only array that owns its data (what
        ``ScanPattern.rotated`` gives: the same array for every frame of a sensor that
        does not move, whose contents cannot change)."""
        return (self.reuse_casts and (np.size(origins) == 3 or _frozen(origins))
                and _frozen(directions))

    def cast(self, origins, directions, max_range, watertight=True, order=None, reuse=False):
        """Per ray: (dist, index into ``geometry``'s triangles or -1, unit normals).
        ``watertight=False`` skips the re-check of misses (for secondary rays);
        ``order`` is a trace order (see ``casting.cast_exact``).

        ``reuse=True`` (for ``reusable`` rays): the result is kept, and when the very
        same rays (same origin, same direction array, range, order) are cast again the
        kept result is given back (as copies, so the caller may change them) instead
        of casting: a static sensor's frames see the same static scene every time. One
        cast is kept, about 40 bytes per ray (4.6 MB for a Pandar64 frame)."""
        return self.start(origins, directions, max_range, watertight, order, reuse)()

    def start(self, origins, directions, max_range, watertight=True, order=None, reuse=False):
        """``cast``, started: returns a function that gives its result. With the
        compiled Embree loop the rays are cast meanwhile, so the caller's own work
        (a frame's random draws) overlaps the cast; other backends cast right here."""
        key = None
        if reuse and watertight and self.reusable(origins, directions):
            one = np.size(origins) == 3
            key = (np.asarray(origins, np.float64).tobytes() if one else origins, directions,
                   float(max_range), order)
            kept = self._kept_cast
            if kept is not None and (isinstance(kept[0][0], bytes) and kept[0][0] == key[0] if one
                                      else kept[0][0] is origins) \
                    and kept[0][1] is directions and kept[0][2] == key[2] \
                    and kept[0][3] is order:
                self.reused += 1
                got = tuple(a.copy() for a in kept[1])
                return lambda: got
        pending = self._start(origins, directions, max_range, watertight, order)
        if key is None:
            return pending

        def kept_result():
            got = pending()
            self._kept_cast = (key, got)
            return tuple(a.copy() for a in got)

        return kept_result

    def _start(self, origins, directions, max_range, watertight, order):
        n = directions.shape[0]
        if self.caster is None or n == 0:
            got = np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))
            return lambda: got
        o = shifted(origins, self.centre)  # read-only: its bounds are kept (column_bounds)
        caster = self.caster if watertight else self.primary
        pending = caster.start_refined(o, directions, max_range, self.planes, order)
        if pending is None:  # a backend that casts from Python: here, refined after
            got = cast_exact(caster, o, directions, max_range, self.planes, order)
            pending = lambda: got  # noqa: E731

        def result():
            dist, tri, normals = pending()
            # Fancy indexing, not take: take slows threefold on the misses' -1.
            return dist, self._to_geometry[tri], normals

        return result


class RigidBodies:
    """Rigidly moving objects, cast together.

    Each object's local-space triangles are laid side by side (each centred on its own
    bounding sphere, spaced well apart) in one shared structure, built once. A ray that
    may meet an object at the ray's scene time is carried into that object's frame by
    the inverse of the object's matrix at that time and shifted to the object's slot;
    all such (ray, object) pairs go through the caster in one batch, and each ray keeps
    its nearest hit. Motion is exact with no sub-steps and no rebuilds.

    parts  [(geometry in local coordinates, Track)], geometries sharing one object and
           one material table
    """

    def __init__(self, parts, caster_factory, watertight=True):
        self.factory, self.watertight = caster_factory, watertight
        self.tracks = [tr for _, tr in parts]
        self.centres, self.radii, self.slots, self.boxes, pieces = [], [], [], [], []
        self.local = []  # per object: (vertices centred on self.centres[k], triangles)
        # Slots are spaced so that a ray started at its own object's box and cast no
        # farther than across it can never reach a neighbour.
        radii = [float(np.linalg.norm(g.vertices - (g.vertices.min(0) + g.vertices.max(0)) / 2,
                                      axis=1).max()) if len(g.vertices) else 0.0
                 for g, _ in parts]
        gap = 2 * max(radii, default=0.0) + 10.0
        offset = 0.0
        slot_of = []
        for k, (g, _) in enumerate(parts):
            v = g.vertices
            lo, hi = (v.min(0), v.max(0)) if len(v) else (np.zeros(3), np.zeros(3))
            c = (lo + hi) / 2
            r = radii[k]
            slot = np.array([offset + r, 0.0, 0.0])
            offset += 2 * r + gap
            slot_of.append(np.full(len(g.triangles), k))
            self.centres.append(c)
            self.radii.append(r)
            pad = 1e-6 * (r + 1.0)
            self.boxes.append((lo - pad, hi + pad))
            self.slots.append(slot)
            pieces.append((v - c + slot, g.triangles, g.tri_object, g.tri_material))
            self.local.append((v - c, np.asarray(g.triangles, np.int64).reshape(-1, 3)))
        first = parts[0][0] if parts else None
        self.geometry = concatenate(pieces, first.objects if first else [],
                                    first.materials if first else [])
        self.tri_start = np.cumsum([0] + [len(t) for _, t in self.local])
        self._box_lo = np.array([b[0] for b in self.boxes]).reshape(-1, 3)
        self._box_hi = np.array([b[1] for b in self.boxes]).reshape(-1, 3)
        self.tri_slot = np.concatenate(slot_of) if slot_of else np.zeros(0, np.int64)
        self._span = offset
        self._scene = self._local_casters = None

    @property
    def tracks(self):
        return self._tracks

    @tracks.setter
    def tracks(self, tracks):
        """This sweep's motion (a cached body is reused over frames with new tracks:
        what was derived from the old ones goes)."""
        self._tracks = list(tracks)
        self._swept_boxes = {}
        self.derived = {}  # other users' values derived from the tracks

    def local_casters(self):
        """Per object: (caster on its own centred triangles, their planes), or None
        for an object with no triangles; built on first use (for Embree instancing,
        see ``instancing.InstancedWorld``)."""
        if self._local_casters is None:
            self._local_casters = [
                (self.factory(v, tri), triangle_planes(v, tri)) if len(tri) else None
                for v, tri in self.local]
        return self._local_casters

    @property
    def scene(self):
        """The objects side by side in their slots, built on first use (a world traced
        with Embree instancing never needs it)."""
        if self._scene is None:
            # Fine hull cells: rays that enter an object's box but miss its surface
            # (most of the pairs cast here) should not look like rays through a crack.
            cell = max(min(self.radii, default=1.0) / 8.0, 0.05)
            self._scene = PreparedScene(self.geometry, np.array([self._span / 2, 0.0, 0.0]),
                                        np.inf, self.factory, self.watertight, hull_cell=cell)
        return self._scene

    def _swept_sphere(self, k):
        """A sphere holding object k over its whole track (for a cheap first cull)."""
        m = self.tracks[k].matrices
        c = np.einsum("kij,j->ki", m[:, :3, :3], self.centres[k]) + m[:, :3, 3]
        stretch = np.linalg.norm(m[:, :3, :3], axis=1).max()
        mid = (c.min(0) + c.max(0)) / 2
        return mid, np.linalg.norm(c - mid, axis=1).max() + self.radii[k] * stretch * 1.01

    def _swept_box(self, k, steps=8):
        """A world-space box holding object k over its whole track: its local box's
        corners at ``steps`` poses per track segment, padded by a quarter of the
        longest corner step (more than the bulge of a smooth path between two poses)
        and 1 mm. Far tighter than the swept sphere: on the benchmark street it keeps a
        quarter of the (ray, car) pairs the sphere lets through."""
        cached = self._swept_boxes.get(k)
        if cached is not None:
            return cached
        track = self.tracks[k]
        t = track.times
        if len(t) > 1:
            t = np.concatenate([np.linspace(a, b, steps, endpoint=False)
                                for a, b in zip(t[:-1], t[1:])] + [t[-1:]])
        m = track.at(t)
        lo, hi = self.boxes[k]
        corners = np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), -1).reshape(-1, 3)
        w = np.einsum("kij,cj->kci", m[:, :3, :3], corners) + m[:, None, :3, 3]
        step = np.linalg.norm(np.diff(w, axis=0), axis=2).max(initial=0.0)
        pad = step / 4 + 1e-3
        box = self._swept_boxes[k] = (w.min(axis=(0, 1)) - pad, w.max(axis=(0, 1)) + pad)
        return box

    def _pairs_each(self, o1, directions, times, max_range, objects=None):
        """(ray index, object index, local origin, local direction, world-to-local linear
        map) for every ray that passes an object's swept bounding sphere and then its
        swept box (of the objects ``objects``, or all). (Vectorising this over all objects at once measured slower: the
        (rays x objects) masks cost more than the loop.)"""
        parts = []
        for k, track in enumerate(self.tracks):
            if objects is not None and k not in objects:
                continue
            centre, radius = self._swept_sphere(k)
            idx = np.nonzero(ray_meets_sphere(o1, directions, centre, radius, max_range))[0]
            if len(idx) == 0:
                continue
            lo, hi = self._swept_box(k)
            t_in, t_out = _ray_box_span(o1 if o1.shape[0] == 1 else o1[idx],
                                        directions.take(idx, axis=0), lo, hi)
            idx = idx[(t_in <= t_out) & (t_out >= 0) & (t_in <= max_range)]
            if len(idx) == 0:
                continue
            o_l, d_l, a_inv = track.rays_to_local(
                times[idx], o1 if o1.shape[0] == 1 else o1.take(idx, axis=0),
                directions.take(idx, axis=0))
            parts.append((idx, np.full(len(idx), k), o_l, d_l,
                          np.broadcast_to(a_inv, (len(idx), 3, 3))))
        if not parts:
            z = np.zeros(0, np.int64)
            return z, z, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3))
        return tuple(np.concatenate([p[j] for p in parts]) for j in range(5))

    def cast(self, origins, directions, times, max_range, watertight=True, objects=None):
        """Per ray: (dist, triangle of ``geometry`` or -1, unit world normal) of its
        nearest hit on these objects (those whose index is in ``objects``, or all), each
        where it is at the ray's time."""
        n = directions.shape[0]
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, np.int64)
        normals = np.zeros((n, 3))
        if self.scene.caster is None or n == 0:
            return dist, tri, normals
        o1 = np.asarray(origins, np.float64).reshape(-1, 3)
        ray, obj, o_l, d_l, a = self._pairs_each(o1, directions, times, max_range, objects)
        if len(ray) == 0:
            return dist, tri, normals
        scale = np.linalg.norm(d_l, axis=1)
        d_l = d_l / scale[:, None]
        # Second cull in each object's own frame at the ray's own time: its box. Each
        # ray then starts where it enters the box, in the object's slot, and is cast no
        # farther than across the box.
        lo = self._box_lo.take(obj, axis=0)
        hi = self._box_hi.take(obj, axis=0)
        t_in, t_out = _ray_box_span(o_l, d_l, lo, hi)
        near = (t_in <= t_out) & (t_out >= 0) & (t_in <= max_range * scale)
        ray, obj, o_l, d_l, a, scale = ray[near], obj[near], o_l[near], d_l[near], a[near], scale[near]
        t_in, t_out = t_in[near], t_out[near]
        if len(ray) == 0:
            return dist, tri, normals
        start = np.maximum(t_in - 1e-6 * (1.0 + np.abs(t_in)), 0.0)
        shift = (np.array(self.slots) - np.array(self.centres))[obj]
        span = float((t_out - start).max()) * (1 + 1e-9) + 1e-6
        dl, tl, nl = self.scene.cast(o_l + shift + d_l * start[:, None], d_l, span, watertight)
        tl = np.where((tl >= 0) & (self.tri_slot[np.maximum(tl, 0)] == obj), tl, -1)
        dl = dl + start
        # Normals go back with the inverse transpose of each object's matrix: A^T.
        nw = np.einsum("nji,nj->ni", a, nl)
        nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-300)
        dw = dl / scale
        ok = np.nonzero((tl >= 0) & (dw <= max_range))[0]
        # Nearest hit per ray (a ray may meet several objects).
        ok = ok[np.lexsort((dw[ok], ray[ok]))]
        first = np.r_[True, ray[ok][1:] != ray[ok][:-1]] if len(ok) else np.zeros(0, bool)
        ok = ok[first]
        sel = ray[ok]
        dist[sel], tri[sel], normals[sel] = dw[ok], tl[ok], nw[ok]
        return dist, tri, normals


def RigidBody(geometry_local, track, caster_factory, watertight=True):
    """One rigidly moving object (see ``RigidBodies``)."""
    return RigidBodies([(geometry_local, track)], caster_factory, watertight)


def ray_meets_sphere(o, d, centre, radius, max_range):
    """Rays (unit d, origins o: one (1, 3) or one per ray) that pass within ``radius``
    of ``centre`` before ``max_range``."""
    rel = centre - o
    if rel.shape[0] == 1:  # one origin: a matrix-vector product, no (N, 3) temporaries
        along = d @ rel[0]
        perp2 = rel[0] @ rel[0] - along ** 2
    else:
        along = np.einsum("ij,ij->i", rel, d)
        perp2 = np.einsum("ij,ij->i", rel, rel) - along ** 2
    return (perp2 <= radius ** 2) & (along + radius >= 0) & (along - radius <= max_range)


def _ray_box_span(o, d, lo, hi):
    """(t_in, t_out) of rays against axis-aligned boxes [lo, hi] (slab test); the ray
    misses where t_in > t_out."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (lo - o) * inv
        t2 = (hi - o) * inv
    # A ray parallel to a slab: inside it (0 * inf = nan there) passes, outside does not.
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    return np.minimum(t1, t2).max(axis=1), np.maximum(t1, t2).min(axis=1)


class TimedScene:
    """A deforming object's world triangles at one sub-step, valid for scene times in
    [t0, t1)."""

    def __init__(self, scene, t0, t1):
        self.scene, self.t0, self.t1 = scene, float(t0), float(t1)
        self.geometry = scene.geometry

    def cast(self, origins, directions, times, max_range, watertight=True):
        n = directions.shape[0]
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, np.int64)
        normals = np.zeros((n, 3))
        idx = np.nonzero((times >= self.t0) & (times < self.t1))[0]
        if len(idx):
            o = np.broadcast_to(np.asarray(origins, np.float64).reshape(-1, 3), directions.shape)
            d, t, nn = self.scene.cast(o[idx], directions[idx], max_range, watertight)
            dist[idx], tri[idx], normals[idx] = d, t, nn
        return dist, tri, normals

