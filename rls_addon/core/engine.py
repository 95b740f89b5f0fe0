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

from . import effects, ghost
from .geometry import clean_for_casting
from .motion import Track, effective_times, polar
from .points import POINT_DTYPE
from .raycast import WatertightCaster, refine_hits, triangle_planes

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

    def covers(self, origin, max_range):
        """True when every ray from ``origin`` (one point or (N, 3)) stays inside the
        culled region."""
        o = np.asarray(origin, np.float64).reshape(-1, 3)
        gap = np.linalg.norm(o - self.centre, axis=1).max()
        return gap + max_range <= self.reach * (1 + 1e-12)

    def cast(self, origins, directions, max_range, watertight=True):
        """Per ray: (dist, index into ``geometry``'s triangles or -1, unit normals).
        ``watertight=False`` skips the re-check of misses (for secondary rays)."""
        n = directions.shape[0]
        if self.caster is None or n == 0:
            return np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))
        o = np.asarray(origins, np.float64).reshape(-1, 3) - self.centre
        caster = self.caster if watertight else getattr(self.caster, "primary", self.caster)
        dist, tri = caster.cast(o, directions, max_range)
        dist, normals = refine_hits(self.vertices, self.triangles, o, directions, dist, tri,
                                    self.planes)
        return dist, np.where(tri >= 0, self.kept[np.maximum(tri, 0)], -1), normals


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
        from .geometry import concatenate

        self.tracks = [tr for _, tr in parts]
        self.centres, self.radii, self.slots, self.boxes, pieces = [], [], [], [], []
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
        first = parts[0][0] if parts else None
        self.geometry = concatenate(pieces, first.objects if first else [],
                                    first.materials if first else [])
        self.tri_slot = np.concatenate(slot_of) if slot_of else np.zeros(0, np.int64)
        # Fine hull cells: rays that enter an object's box but miss its surface (most of
        # the pairs cast here) should not look like rays through a crack.
        cell = max(min(self.radii, default=1.0) / 8.0, 0.05)
        self.scene = PreparedScene(self.geometry, np.array([offset / 2, 0.0, 0.0]), np.inf,
                                   caster_factory, watertight, hull_cell=cell)

    def _swept_sphere(self, k):
        """A sphere holding object k over its whole track (for a cheap first cull)."""
        m = self.tracks[k].matrices
        c = np.einsum("kij,j->ki", m[:, :3, :3], self.centres[k]) + m[:, :3, 3]
        stretch = np.linalg.norm(m[:, :3, :3], axis=1).max()
        mid = (c.min(0) + c.max(0)) / 2
        return mid, np.linalg.norm(c - mid, axis=1).max() + self.radii[k] * stretch * 1.01

    def _pairs_each(self, o1, directions, times, max_range):
        """(ray index, object index, local origin, local direction, world-to-local linear
        map) for every ray that passes an object's swept bounding sphere. (Vectorising
        this over all objects at once measured slower: the (rays x objects) masks cost
        more than the loop.)"""
        o = np.broadcast_to(o1, directions.shape)
        parts = []
        for k, track in enumerate(self.tracks):
            centre, radius = self._swept_sphere(k)
            idx = np.nonzero(_ray_meets_sphere(o1, directions, centre, radius, max_range))[0]
            if len(idx) == 0:
                continue
            a_inv, b_inv = track.inverse_at(times[idx])
            if a_inv.ndim == 2:
                a_inv = np.broadcast_to(a_inv, (len(idx), 3, 3))
            o_l = np.einsum("nij,nj->ni", a_inv, o[idx]) + b_inv
            d_l = np.einsum("nij,nj->ni", a_inv, directions[idx])
            parts.append((idx, np.full(len(idx), k), o_l, d_l, a_inv))
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
        lo = np.array([b[0] for b in self.boxes])[obj]
        hi = np.array([b[1] for b in self.boxes])[obj]
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
    """Everything a sweep can hit. Body 0 is the static scene; the geometries of all
    bodies share one object table and one material table."""

    static: PreparedScene
    moving: list = field(default_factory=list)  # RigidBody and TimedScene

    @property
    def bodies(self):
        return [self.static] + list(self.moving)

    def cast(self, origins, directions, times, max_range, watertight=True):
        """Nearest hit over all bodies: (dist, body index, triangle index, normals)."""
        dist, tri, normals = self.static.cast(origins, directions, max_range, watertight)
        body = np.where(tri >= 0, 0, -1)
        for k, b in enumerate(self.moving, start=1):
            d2, t2, n2 = b.cast(origins, directions, times, max_range, watertight)
            closer = (t2 >= 0) & (d2 < dist)
            dist[closer], tri[closer], normals[closer], body[closer] = \
                d2[closer], t2[closer], n2[closer], k
        return dist, body, tri, normals

    def per_hit(self, body, tri, name):
        """Gather a per-triangle field (see ``SceneGeometry.per_triangle``) at hits."""
        if not self.moving:
            return self.static.geometry.per_triangle(name)[tri]
        out = None
        for k, b in enumerate(self.bodies):
            sel = body == k
            if not sel.any():
                continue
            values = b.geometry.per_triangle(name)[tri[sel]]
            if out is None:
                out = np.zeros(len(body), dtype=values.dtype)
            out[sel] = values
        return out if out is not None else np.zeros(len(body))


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
class Hits:
    """Hit records of the rays that returned something (one row per ray in ``idx``)."""

    idx: np.ndarray       # ray index into the pattern
    dist: np.ndarray      # range (for ghosts: total path a + b)
    body: np.ndarray      # body index in World.bodies
    tri: np.ndarray       # triangle index in that body's geometry
    normals: np.ndarray   # unit normal of the surface that sent the light back
    u: np.ndarray         # beam direction (world)
    u_last: np.ndarray    # direction of the last leg (reflected direction for ghosts)
    ghost: np.ndarray     # uint8 flag
    mirror: np.ndarray    # reflectivity of the mirror a ghost came through (1 otherwise)

    def take(self, keep):
        """The rows where boolean (or index) ``keep`` selects; self when it keeps all."""
        if keep.dtype == bool and keep.all():
            return self
        return Hits(*(getattr(self, f)[keep] for f in self.__dataclass_fields__))


def _ghosts(world, rng, origins, times, h, rmax):
    """Turn a seeded share of glossy hits into ghost points at total path a + b along
    the beam, labelled as the object the reflected beam found; glossy hits whose
    reflected beam finds nothing return nothing. Returns (Hits, stats)."""
    n = len(h.dist)
    labels = ghost.glossy_labels()
    glossy, ratio, mirror = np.zeros(n, bool), np.zeros(n), np.ones(n)
    for k, b in enumerate(world.bodies):
        sel = h.body == k
        if sel.any():
            g, r, refl = ghost.glossy_triangles(b.geometry, labels)
            glossy[sel], ratio[sel], mirror[sel] = g[h.tri[sel]], r[h.tri[sel]], refl[h.tri[sel]]
    gi = np.nonzero(glossy)[0]
    stats = {"glossy_hits": int(len(gi)), "ghosts": 0, "bounce_rays": 0}
    if len(gi) == 0:
        return h, stats
    chosen = gi[rng.random(len(gi)) < ratio[gi]]
    if len(chosen) == 0:
        return h, stats
    a, uc = h.dist[chosen], h.u[chosen]
    o = origins if origins.shape[0] == 1 else origins[h.idx[chosen]]
    r = ghost.reflect(uc, h.normals[chosen])
    p = o + uc * a[:, None]
    start = ghost.bounce_origins(p, uc, h.normals[chosen], a)
    # Reflected beams start on a surface, inside its cluster box: the watertight re-check
    # would re-cast every one that escapes to the sky. A crack missed by a ghost ray
    # only loses one ghost point, so they are cast once.
    b, body2, tri2, n2 = world.cast(start, r, times[h.idx[chosen]], rmax, watertight=False)
    found = tri2 >= 0
    # The second leg measured from the mirror point itself, not the lifted start.
    b = np.where(found, np.linalg.norm(start + r * np.where(found, b, 0)[:, None] - p, axis=1), b)
    found &= a + b <= rmax
    g = chosen[found]
    out = h.take(np.arange(n))  # a copy
    out.dist[g] = a[found] + b[found]
    out.body[g], out.tri[g], out.normals[g] = body2[found], tri2[found], n2[found]
    out.u_last[g] = r[found]
    out.ghost[g] = 1
    out.mirror[g] = mirror[g]
    keep = np.ones(n, bool)
    keep[chosen[~found]] = False
    stats.update(ghosts=int(len(g)), bounce_rays=int(len(chosen)))
    return out.take(keep), stats


def _inside_warnings(world, h, min_hits=100, share=0.95):
    """Warn when nearly all hits on an object land on the back of its faces: the sensor
    is inside it (fine for a tunnel or a room; a mistake for a solid object)."""
    if len(h.idx) < min_hits:
        return []
    back = np.einsum("ij,ij->i", h.u_last, h.normals) > 0
    inst = world.per_hit(h.body, h.tri, "instance").astype(np.int64)
    total = np.bincount(inst)
    behind = np.bincount(inst, weights=back)
    suspects = np.nonzero((total >= min_hits) & (behind >= share * np.maximum(total, 1)))[0]
    if len(suspects) == 0:
        return []
    objects = {o.instance: o.name for b in world.bodies for o in b.geometry.objects}
    return [f"the sensor is inside '{objects.get(int(i), i)}' ({behind[i] / total[i]:.0%} of "
            f"its {int(total[i])} hits are on the back of its faces); fine for a room or "
            "tunnel, otherwise move the sensor" for i in suspects]


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
    t0 = time.perf_counter()
    s = settings
    rmin, rmax = resolve_range(preset, s)
    sigma = preset.range.noise_sigma_m if s.noise_sigma_m is None else s.noise_sigma_m
    atten = preset.attenuation_per_m if s.attenuation_per_m is None else s.attenuation_per_m
    rng, ghost_rng = effects.scan_rng(s.seed, sensor, frame)

    n = len(pattern)
    tscene = effective_times(pattern.times, pattern.period, s.motion, s.substeps)
    track = sensor_track if sensor_track is not None else Track.fixed(sensor_to_world)
    dirs_sensor = pattern.directions
    if track.is_static:
        origin, rot = sensor_axes(track.matrices[0])
        origins = origin.reshape(1, 3)
        dirs = dirs_sensor @ rot.T
    else:
        origins, rots = sensor_axes(track.at(tscene))
        dirs = np.einsum("nij,nj->ni", rots, dirs_sensor)
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

    dist, body, tri, normals = world.cast(origins, dirs, tscene, rmax)
    idx = np.nonzero((tri >= 0) & (dist >= rmin) & (dist <= rmax))[0]
    h = Hits(idx, dist[idx], body[idx], tri[idx], normals[idx], dirs[idx], dirs[idx].copy(),
             np.zeros(len(idx), np.uint8), np.ones(len(idx)))
    stats = {"glossy_hits": 0, "ghosts": 0, "bounce_rays": 0}
    if s.ghosting and len(idx):
        h, stats = _ghosts(world, ghost_rng, origins, tscene, h, rmax)

    refl = world.per_hit(h.body, h.tri, "reflectivity").astype(np.float64)
    cosi = effects.incidence_cosine(h.u_last, h.normals)
    inten = effects.intensity(refl, cosi, h.dist, atten) * h.mirror
    # Noise and dropout are drawn per ray, not per hit, so a ray's draws never depend on
    # which other rays returned (ghosting or moving objects change only their own rays).
    d = h.dist
    if s.noise:
        d = d + effects.range_noise(rng, n, sigma)[h.idx]
    if s.dropout:
        keep = effects.dropout_keep(rng, inten, preset.dropout.general_rate,
                                    preset.dropout.intensity_limit, preset.dropout.intensity_zero,
                                    rays=h.idx, n_rays=n)
    else:
        keep = np.ones(len(d), bool)
    keep &= d > 0
    h, d, inten = h.take(keep), d[keep], inten[keep]
    idx = h.idx
    o_hit = origins if origins.shape[0] == 1 else origins[idx]

    warnings += _inside_warnings(world, h)
    pts = np.zeros(len(idx), dtype=POINT_DTYPE)
    xyz = o_hit + h.u * d[:, None] if s.frame_space == "world" else dirs_sensor[idx] * d[:, None]
    pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    pts["range"] = d
    pts["intensity"] = inten
    pts["ring"] = pattern.channels[idx]
    pts["time"] = pattern.times[idx]
    pts["label"] = world.per_hit(h.body, h.tri, "label")
    pts["instance"] = world.per_hit(h.body, h.tri, "instance")
    pts["ghost"] = h.ghost
    stats["moving_bodies"] = len(moving)
    return ScanResult(pts, n, len(scene.triangles), time.perf_counter() - t0, warnings, stats)
