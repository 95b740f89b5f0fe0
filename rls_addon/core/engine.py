"""The scan engine: one frame of one sensor, from triangles and a pattern to points.

Pure numpy around a ray-casting backend handed in by the caller (see ``raycast``).

The world is made of bodies, each prepared once and cast into as needed:
- ``PreparedScene``: static triangles in centre-relative coordinates;
- ``RigidBody``: one moving object's triangles in its own local coordinates with a
  ``Track`` of its pose over the sweep; every ray is carried into the object's frame
  at the ray's own scene time, so motion is exact with no sub-steps and no rebuilds;
- ``TimedScene``: a deforming object's triangles at one sub-step, valid for rays whose
  scene time falls into that sub-step.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from . import blas, effects, ghost
from .geometry import ObjectInfo, SceneGeometry, clean_for_casting, concatenate
from .instancing import InstancedWorld
from .motion import effective_times, polar
from .points import POINT_DTYPE
from .raycast import WatertightCaster, cast_exact, triangle_planes

MOTION_MODES = ("exact", "substeps", "snapshot")


@dataclass(frozen=True)
class ScanSettings:
    """What a user chooses for a scan, beyond the device preset.

    Range and noise fields left as None take the preset's values."""

    seed: int = 0
    frame_space: str = "sensor"  # "sensor" or "world"
    noise: bool = True
    dropout: bool = True
    min_range_m: float | None = None
    max_range_m: float | None = None
    noise_sigma_m: float | None = None
    attenuation_per_m: float | None = None
    # Motion distortion: "exact" (every ray at its own time), "substeps" (the paper's
    # N partial sweeps) or "snapshot" (one scene state per frame, as CARLA).
    motion: str = "exact"
    substeps: int = 0  # 0: chosen adaptively for deforming objects; N: fixed
    motion_tolerance_m: float | None = None  # adaptive sub-step tolerance (None: preset)
    ghosting: bool = True  # ghost points from glossy surfaces


@dataclass
class ScanResult:
    points: np.ndarray
    rays: int
    triangles: int
    seconds: float
    warnings: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)


def _make_caster(factory, vertices, triangles, groups, watertight, hull_cell=None):
    if not len(triangles):
        return None
    if watertight:
        return WatertightCaster(factory, vertices, triangles, groups, hull_cell)
    return factory(vertices, triangles)


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
        self.caster = _make_caster(caster_factory, self.vertices, self.triangles,
                                   geometry.tri_object[self.kept], watertight, hull_cell)
        self.backend = getattr(self.caster, "name", "none")
        self.planes = triangle_planes(self.vertices, self.triangles)
        # Caster triangle -> geometry triangle, with a trailing -1 that misses (-1) pick.
        self._to_geometry = np.append(self.kept, -1).astype(np.int64)
        self._kept_cast = None
        self.reused = 0  # casts answered from the kept one

    def covers(self, origin, max_range):
        """True when every ray from ``origin`` (one point or (N, 3)) stays inside the
        culled region."""
        o = np.asarray(origin, np.float64).reshape(-1, 3)
        gap = np.linalg.norm(o - self.centre, axis=1).max()
        return gap + max_range <= self.reach * (1 + 1e-12)

    def reusable(self, origins, directions):
        """True when ``cast(..., reuse=True)`` may keep or reuse a cast of these rays:
        one origin, and directions in a read-only array that owns its data (what
        ``ScanPattern.rotated`` gives: the same array for every frame of a sensor that
        does not move, whose contents cannot change)."""
        return (self.reuse_casts and np.size(origins) == 3
                and isinstance(directions, np.ndarray) and directions.base is None
                and not directions.flags.writeable)

    def cast(self, origins, directions, max_range, watertight=True, order=None, reuse=False):
        """Per ray: (dist, index into ``geometry``'s triangles or -1, unit normals).
        ``watertight=False`` skips the re-check of misses (for secondary rays);
        ``order`` is a trace order (see ``raycast.cast_exact``).

        ``reuse=True`` (for ``reusable`` rays): the result is kept, and when the very
        same rays (same origin, same direction array, range, order) are cast again the
        kept result is given back (as copies, so the caller may change them) instead
        of casting: a static sensor's frames see the same static scene every time. One
        cast is kept, about 40 bytes per ray (4.6 MB for a Pandar64 frame)."""
        key = None
        if reuse and watertight and self.reusable(origins, directions):
            key = (np.asarray(origins, np.float64).tobytes(), directions,
                   float(max_range), order)
            kept = self._kept_cast
            if kept is not None and kept[0][0] == key[0] and kept[0][1] is directions \
                    and kept[0][2] == key[2] and kept[0][3] is order:
                self.reused += 1
                return tuple(a.copy() for a in kept[1])
        got = self._cast(origins, directions, max_range, watertight, order)
        if key is not None:
            self._kept_cast = (key, got)
            return tuple(a.copy() for a in got)
        return got

    def _cast(self, origins, directions, max_range, watertight, order):
        n = directions.shape[0]
        if self.caster is None or n == 0:
            return np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))
        o = np.asarray(origins, np.float64).reshape(-1, 3) - self.centre
        caster = self.caster if watertight else getattr(self.caster, "primary", self.caster)
        dist, tri, normals = cast_exact(caster, o, directions, max_range, self.planes, order)
        return dist, self._to_geometry.take(tri), normals

    def start_cast(self, origins, directions, max_range):
        """Start ``cast(..., watertight=False)`` and return a function that gives its
        result. Backends that cast without Python (the compiled Embree loop) run
        meanwhile, so the caller can do other work; the others cast right here."""
        caster = getattr(self.caster, "primary", self.caster)
        start = getattr(caster, "start_refined", None)
        pending = None
        if start is not None and len(directions):
            o = np.asarray(origins, np.float64).reshape(-1, 3) - self.centre
            pending = start(o, directions, max_range, self.planes)
        if pending is None:
            got = self.cast(origins, directions, max_range, watertight=False)
            return lambda: got

        def result():
            dist, tri, normals = pending()
            return dist, self._to_geometry.take(tri), normals

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

    def _pairs_each(self, o1, directions, times, max_range):
        """(ray index, object index, local origin, local direction, world-to-local linear
        map) for every ray that passes an object's swept bounding sphere and then its
        swept box. (Vectorising this over all objects at once measured slower: the
        (rays x objects) masks cost more than the loop.)"""
        parts = []
        for k, track in enumerate(self.tracks):
            centre, radius = self._swept_sphere(k)
            idx = np.nonzero(_ray_meets_sphere(o1, directions, centre, radius, max_range))[0]
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

    def cast(self, origins, directions, times, max_range, watertight=True):
        n = directions.shape[0]
        dist = np.full(n, np.inf)
        tri = np.full(n, -1, np.int64)
        normals = np.zeros((n, 3))
        if self.scene.caster is None or n == 0:
            return dist, tri, normals
        o1 = np.asarray(origins, np.float64).reshape(-1, 3)
        ray, obj, o_l, d_l, a = self._pairs_each(o1, directions, times, max_range)
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


def _ray_meets_sphere(o, d, centre, radius, max_range):
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


@dataclass
class World:
    """Everything a sweep can hit. Body 0 is the static scene. The scene extraction
    gives every body the same object and material tables; bodies built with their own
    tables (tests, scripts) get them joined, with per-body index offsets."""

    static: PreparedScene
    moving: list = field(default_factory=list)  # RigidBody and TimedScene

    def __post_init__(self):
        self._instanced = False  # not built yet
        geos = [b.geometry for b in self.bodies]
        base = geos[0]
        self._offsets = None
        if all(g.objects == base.objects and g.materials == base.materials for g in geos[1:]):
            self._tables = base
            return
        self._offsets = np.cumsum([[0, 0]] + [[len(g.objects) or 1, len(g.materials)]
                                              for g in geos[:-1]], axis=0).astype(np.int32)
        self._tables = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), [], [],
                                     [o for g in geos for o in (g.objects or [ObjectInfo("")])],
                                     [m for g in geos for m in g.materials])

    @property
    def bodies(self):
        return [self.static] + list(self.moving)

    @property
    def instanced(self):
        """The static scene and the rigidly moving bodies as one Embree traversal
        (``instancing.InstancedWorld``), or None (other backends, or nothing moves
        rigidly): built on first use."""
        if self._instanced is False:
            self._instanced = InstancedWorld.build(self.static, self.moving) \
                if self.moving else None
        return self._instanced

    def cast(self, origins, directions, times, max_range, watertight=True, order=None,
             reuse=False):
        """Nearest hit over all bodies: (dist, body index, triangle index, normals);
        ``order``: a trace order for the static scene (see ``raycast.cast_exact``).
        ``reuse``: the static scene's part may come from its previous cast of the same
        rays (see ``PreparedScene.cast``); only the moving bodies are cast then."""
        return self._start(origins, directions, times, max_range, watertight, order, reuse)()

    def start_cast(self, origins, directions, times, max_range):
        """Start ``cast(..., watertight=False)``; returns a function giving its result.
        With the compiled Embree loop the cast runs meanwhile (see
        ``PreparedScene.start_cast``); bodies cast on their own are cast right here."""
        return self._start(origins, directions, times, max_range, False, None)

    def _start(self, origins, directions, times, max_range, watertight, order, reuse=False):
        rest = list(enumerate(self.moving, start=1))
        reuse = reuse and watertight and self.static.reusable(origins, directions)
        if reuse:
            # The static scene cast on its own, through its store of the last cast; the
            # moving bodies traced without it (as instances, or each on its own) and
            # merged in below: the nearer hit wins, as in one traversal.
            inst = InstancedWorld.build(self.static, self.moving, with_static=False) \
                if self.moving else None
        else:
            inst = self.instanced
        if inst is not None:
            rest = [(k, b) for k, b in rest if k not in inst.traced]
        if inst is not None and not reuse:  # the static scene among the instances
            pending = inst.start(origins, directions, times, max_range, order, watertight)
        elif not rest and not watertight:  # (reuse is watertight)
            started = self.static.start_cast(origins, directions, max_range)
            pending = lambda: _static_hits(*started())  # noqa: E731
        else:
            got = _static_hits(*self.static.cast(origins, directions, max_range, watertight,
                                                 order, reuse))
            pending = lambda: got  # noqa: E731
            if inst is not None:  # the moving bodies, as instances without the static scene
                movers = inst.start(origins, directions, times, max_range, order, True)
                pending = lambda: _nearer(got, movers())  # noqa: E731
        if not rest:
            return pending
        # Bodies cast on their own (deforming sub-steps; every body on backends that
        # cannot instance): their nearest hits are merged in.
        more = [(k, b.cast(origins, directions, times, max_range, watertight)) for k, b in rest]

        def merged():
            got = pending()
            for k, (d2, t2, n2) in more:
                got = _nearer(got, (d2, np.where(t2 >= 0, k, -1), t2, n2))
            return got

        return merged

    @property
    def geometry(self):
        """A geometry holding the object and material tables of every body (the
        indices ``surface_ids`` gives point into them)."""
        return self._tables

    def surface_ids(self, body, tri):
        """(N, 2) int32 (object index, material index) of the surface each ray hit, into
        the shared tables (see ``SceneGeometry.surface_ids``); rows with no hit (body
        -1) hold arbitrary valid indices."""
        # Most rows are static: one gather for all, then the few others redone.
        # take(axis=0): numpy's fancy indexing copies rows one by one, ~8x slower.
        t = self.static.geometry.surface_ids()
        rows = np.where(body == 0, tri, 0) if self.moving else tri
        out = t.take(rows, axis=0) if len(t) else np.zeros((len(tri), 2), np.int32)
        for k, b in enumerate(self.moving, start=1):
            sel = np.nonzero(body == k)[0]
            if len(sel):
                out[sel] = b.geometry.surface_ids().take(tri[sel], axis=0)
                if self._offsets is not None:
                    out[sel] += self._offsets[k]
        return out


def _static_hits(dist, tri, normals):
    """A static scene's cast as a world's: (dist, body 0 where it hit else -1, tri,
    normals)."""
    return dist, np.where(tri >= 0, 0, -1), tri, normals


def _nearer(got, other):
    """Merge two (dist, body, tri, normals) casts of the same rays into ``got``: per
    ray, the nearer hit (``other``'s where it hit something closer)."""
    dist, body, tri, normals = got
    d2, b2, t2, n2 = other
    closer = (b2 >= 0) & (d2 < dist)
    dist[closer], body[closer], tri[closer], normals[closer] = \
        d2[closer], b2[closer], t2[closer], n2[closer]
    return dist, body, tri, normals


def sensor_axes(sensor_to_world):
    """Origins and orthonormal rotations of 4x4 poses (one (4, 4) or a stack (N, 4, 4));
    scale and shear are removed, and a mirrored sensor still looks along its own axes."""
    m = np.asarray(sensor_to_world, dtype=np.float64)
    rot, _ = polar(m.reshape(-1, 4, 4)[:, :3, :3])
    return m[..., :3, 3].copy(), rot.reshape(m.shape[:-2] + (3, 3))


def resolve_range(preset, settings):
    """(min, max) range in metres after the settings' overrides."""
    rmin = preset.range.min_m if settings.min_range_m is None else settings.min_range_m
    rmax = preset.range.max_m if settings.max_range_m is None else settings.max_range_m
    return rmin, rmax


@dataclass
class Returns:
    """What each ray of the pattern brought back, one row per ray (kept per ray, not
    compacted per hit, so no step copies the records: rows are selected once, for the
    points)."""

    valid: np.ndarray     # the ray returned a point within range
    dist: np.ndarray      # range (for ghosts: total path a + b)
    surface: np.ndarray   # (N, 2) object and material index of what sent the light back
    normals: np.ndarray   # unit normal of that surface
    ghost: np.ndarray | None = None  # uint8 flag per ray (None: no ghosts)


class _Bounces:
    """Ghost points from glossy surfaces, in two steps around the frame's other work.

    ``__init__`` picks a seeded share of the glossy returns (drawn per ray, so one
    ray's fate never depends on which other rays returned) and starts casting their
    reflected beams (see ``World.start_cast``: with the compiled Embree loop the
    frame's per-ray shading goes on meanwhile).
    ``finish`` turns the beams that found something into ghost points at total path
    a + b along the original beam, labelled as what the reflected beam found; glossy
    returns whose reflected beam finds nothing return nothing."""

    def __init__(self, world, rng, origins, dirs, times, ret, rmax):
        self.world, self.rmax = world, rmax
        obj_glossy, mat_glossy, mat_ratio = ghost.glossy_tables(world.geometry,
                                                                ghost.glossy_labels())
        obj, mat = ret.surface[:, 0], ret.surface[:, 1]
        glossy = mat_glossy[mat]
        if obj_glossy.any():
            glossy |= obj_glossy[obj]
        cand = np.nonzero(glossy & ret.valid)[0]
        self.stats = {"glossy_hits": int(len(cand)), "ghosts": 0, "bounce_rays": 0}
        self.chosen = cand[rng.random(len(ret.dist))[cand] < mat_ratio[mat[cand]]] \
            if len(cand) else cand
        self.stats["bounce_rays"] = int(len(self.chosen))
        self.pending = None
        if len(self.chosen) == 0:
            return
        c = self.chosen
        self.a = ret.dist[c]
        uc, nc = dirs.take(c, axis=0), ret.normals.take(c, axis=0)
        o = origins if origins.shape[0] == 1 else origins[c]
        self.r = ghost.reflect(uc, nc)
        self.p = o + uc * self.a[:, None]
        # Reflected beams start on a surface, inside its cluster box: the watertight
        # re-check would re-cast every one that escapes to the sky. A crack missed by a
        # ghost ray only loses one ghost point, so they are cast once.
        self.start = ghost.bounce_origins(self.p, uc, nc, self.a)
        self.pending = world.start_cast(self.start, self.r, times[c], rmax)

    def finish(self, ret):
        """Apply the bounces to ``ret``; returns (ghost rows, their last-leg
        directions, their mirrors' reflectivity)."""
        none = np.zeros(0, np.int64)
        if len(self.chosen) == 0:
            return none, np.zeros((0, 3)), np.zeros(0)
        b, body2, tri2, n2 = self.pending()
        found = tri2 >= 0
        # The second leg measured from the mirror point itself, not the lifted start.
        b = np.where(found, np.linalg.norm(
            self.start + self.r * np.where(found, b, 0)[:, None] - self.p, axis=1), b)
        found &= self.a + b <= self.rmax
        fi = np.nonzero(found)[0]
        g = self.chosen[fi]
        ret.valid[self.chosen[~found]] = False
        self.stats["ghosts"] = int(len(g))
        if len(g) == 0:
            return none, np.zeros((0, 3)), np.zeros(0)
        mirror = self.world.geometry.material_field("reflectivity")[ret.surface[g, 1]]
        ret.dist[g] = self.a[fi] + b[fi]
        ret.surface[g] = self.world.surface_ids(body2[fi], tri2[fi])
        ret.normals[g] = n2.take(fi, axis=0)
        ret.ghost = np.zeros(len(ret.dist), np.uint8)
        ret.ghost[g] = 1
        return g, self.r.take(fi, axis=0), mirror


def _inside_warnings(world, obj, back, min_hits=100, share=0.95):
    """Warn when nearly all points on an object land on the back of its faces: the
    sensor is inside it (fine for a tunnel or a room; a mistake for a solid object).
    ``obj`` (index into ``world.geometry.objects``) and ``back`` (bool) are per point."""
    if len(obj) < min_hits or np.count_nonzero(back) < min_hits:
        return []
    objects = world.geometry.objects
    behind = np.bincount(obj[back], minlength=len(objects))
    cand = np.nonzero(behind >= min_hits)[0]  # a suspect has that many back hits
    if len(cand) == 0:
        return []
    # All hits of the candidates: for a few, one comparison each; else one count.
    total = np.array([np.count_nonzero(obj == c) for c in cand]) if len(cand) <= 4 \
        else np.bincount(obj, minlength=len(objects))[cand]
    sel = behind[cand] >= share * total
    return [f"the sensor is inside '{objects[i].name if i < len(objects) else i}' "
            f"({behind[i] / t:.0%} of its {int(t)} hits are on the back of its "
            "faces); fine for a room or tunnel, otherwise move the sensor"
            for i, t in zip(cand[sel], total[sel])]


def scan_frame(scene, pattern, sensor_to_world, preset, settings, caster_factory=None,
               frame=0, sensor="sensor", sensor_track=None, moving=()):
    """Scan one frame.

    scene            PreparedScene covering the sensor, or a SceneGeometry (world
                     coordinates), prepared here around the sensor with caster_factory
    pattern          ScanPattern (directions in the sensor frame, per-ray times)
    sensor_to_world  4x4 pose of the sensor at the start of the sweep
    sensor_track     optional Track of the sensor over the sweep (a moving sensor)
    moving           RigidBody / TimedScene bodies (moving and deforming objects)
    Returns a ScanResult whose points follow ``POINT_DTYPE``; sensor-frame points are
    as the device reports them (each in the sensor frame at its own firing time).
    """
    with blas.single_threaded():  # OpenBLAS' spinning threads would slow the caster
        return _scan_frame(scene, pattern, sensor_to_world, preset, settings, caster_factory,
                           frame, sensor, sensor_track, moving)


def _scan_frame(scene, pattern, sensor_to_world, preset, settings, caster_factory, frame,
                sensor, sensor_track, moving):
    t0 = time.perf_counter()
    s = settings
    rmin, rmax = resolve_range(preset, s)
    sigma = preset.range.noise_sigma_m if s.noise_sigma_m is None else s.noise_sigma_m
    atten = preset.attenuation_per_m if s.attenuation_per_m is None else s.attenuation_per_m
    rng, ghost_rng = effects.scan_rng(s.seed, sensor, frame)

    n = len(pattern)
    tscene = effective_times(pattern.times, pattern.period, s.motion, s.substeps)
    dirs_sensor = pattern.directions
    if sensor_track is None or sensor_track.is_static:
        origin, rot = sensor_axes(sensor_to_world if sensor_track is None
                                  else sensor_track.matrices[0])
        origins = origin.reshape(1, 3)
        dirs = pattern.rotated(rot)
    else:
        # One pose per distinct firing time (the channels of a firing share it): a
        # spinning lidar has 64 to 128 times fewer poses to take apart than rays.
        times, at = np.unique(tscene, return_inverse=True)
        origins, rots = sensor_axes(sensor_track.at(times))
        origins = origins[at]
        dirs = np.einsum("nij,nj->ni", rots[at], dirs_sensor)
    if not isinstance(scene, PreparedScene):
        scene = PreparedScene(scene, origins.mean(axis=0),
                              rmax + np.ptp(origins, axis=0).max(initial=0.0), caster_factory)
    elif not scene.covers(origins, rmax):
        raise ValueError("the prepared scene does not cover this sensor's range")
    world = World(scene, list(moving))
    warnings = list(scene.warnings)
    if scene.geometry.triangle_count == 0 and not moving:
        warnings.append("the scene has no geometry to scan")
    elif len(scene.triangles) == 0 and not moving:
        warnings.append(f"no geometry within {rmax:g} m of the sensor")

    # A sensor that does not move casts the same rays into the same static scene every
    # frame: the static part is cast once and reused (see PreparedScene.cast).
    reused = scene.reused
    dist, body, tri, normals = world.cast(origins, dirs, tscene, rmax,
                                         order=pattern.trace_order, reuse=True)
    reused = scene.reused > reused
    ret = Returns((tri >= 0) & (dist >= rmin) & (dist <= rmax), dist,
                  world.surface_ids(body, tri), normals)
    bounces = _Bounces(world, ghost_rng, origins, dirs, tscene, ret, rmax) \
        if s.ghosting and ret.valid.any() else None

    # Per ray from here on (misses carry harmless values and are dropped at the end);
    # ghost rows are redone once their reflected beams are back.
    g = world.geometry
    refl = g.material_field("reflectivity").astype(np.float64)
    dot = np.einsum("ij,ij->i", dirs, ret.normals)  # > 0: the back of a face
    inten = effects.intensity(refl[ret.surface[:, 1]], np.abs(dot),
                              np.where(ret.valid, ret.dist, 0.0) if atten else None, atten)
    # Noise and dropout are drawn per ray, not per hit, so a ray's draws never depend on
    # which other rays returned (ghosting or moving objects change only their own rays).
    noise = effects.range_noise(rng, n, sigma) if s.noise else None
    stats = {"glossy_hits": 0, "ghosts": 0, "bounce_rays": 0}
    if bounces is not None:
        rows, last_leg, mirror = bounces.finish(ret)
        stats = bounces.stats
        if len(rows):
            dot[rows] = np.einsum("ij,ij->i", last_leg, ret.normals.take(rows, axis=0))
            inten[rows] = mirror * effects.intensity(refl[ret.surface[rows, 1]],
                                                     np.abs(dot[rows]), ret.dist[rows], atten)
    d = ret.dist if noise is None else ret.dist + noise
    keep = ret.valid
    if s.dropout:
        keep &= effects.dropout_keep(rng, inten, preset.dropout.general_rate,
                                     preset.dropout.intensity_limit,
                                     preset.dropout.intensity_zero)
    keep &= d > 0
    idx = np.nonzero(keep)[0]
    obj = ret.surface[:, 0]
    d = d[idx]
    o_idx = obj[idx]
    instance = g.object_field("instance")[o_idx]
    warnings += _inside_warnings(world, o_idx, dot[idx] > 0)

    pts = np.empty(len(idx), dtype=POINT_DTYPE)
    if s.frame_space == "world":
        cols = dirs.T
        for k, f in enumerate("xyz"):
            np.multiply(cols[k][idx], d, out=pts[f])
            pts[f] += origins[0, k] if origins.shape[0] == 1 else origins[idx, k]
    else:
        cols = pattern.columns
        for k, f in enumerate("xyz"):
            np.multiply(cols[k].take(idx), d, out=pts[f])
    pts["range"] = d
    pts["intensity"] = inten.take(idx)
    pts["ring"] = pattern.channels.take(idx)
    pts["time"] = pattern.times.take(idx)
    pts["label"] = g.object_field("label")[o_idx]
    pts["instance"] = instance
    pts["ghost"] = 0 if ret.ghost is None else ret.ghost.take(idx)
    stats["moving_bodies"] = len(moving)
    stats["static_cast_reused"] = reused
    return ScanResult(pts, n, len(scene.triangles), time.perf_counter() - t0, warnings, stats)
