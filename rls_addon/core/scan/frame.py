"""One frame of one sensor: from a prepared scene, the moving bodies and a scan pattern
to points. The per-ray pipeline after casting (ranges, ghosts, intensity, noise,
dropout, point records) lives here; where the rays go is in ``aim``, what is cast into
in ``bodies`` and ``world``.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from . import freed_pages
from ..native import blas_threads
from ..physics import echoes, effects, footprint, ghost, weather
from ..physics.assemble import Draws, Effects, Hits, Rays, assemble
from ..world.bodies import PreparedScene
from ..errors import SceneError
from ..scene.motion import effective_times
# sensor_axes, sensor_frame and distinct_times are imported from here too
from .aim import _Aim, distinct_times, sensor_axes, sensor_frame  # noqa: F401
from .device_values import DeviceValues, device_values
from .sweep import adaptive_substeps
from ..native.vectors import row_dot
from ..world.world import World


@dataclass
class ScanResult:
    points: np.ndarray
    rays: int
    triangles: int
    seconds: float
    warnings: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    rays_cast: "RayRecord" = None  # with scan_frame(keep_rays=True)


@dataclass
class RayRecord:
    """Every ray of a frame and what it hit first, for ground truth (visibility of
    objects, the world position of each point). World coordinates.

    origins   (1, 3) or (N, 3) ray origins (per ray for a moving sensor)
    dirs      (N, 3) unit directions
    times     (N,) firing times, seconds since the sweep start
    object    (N,) int32 index into ``objects`` of the first surface hit (-1: nothing
              within range); a glossy hit is the mirror, not its ghost
    dist      (N,) float64 range to that hit (inf: nothing)
    point_ray (P,) int64 the ray of each returned point
    objects   the ObjectInfo table ``object`` indexes"""

    origins: np.ndarray
    dirs: np.ndarray
    times: np.ndarray
    object: np.ndarray
    dist: np.ndarray
    point_ray: np.ndarray
    objects: list

    def point_world(self, ranges):
        """(P, 3) world position of the points of ranges ``ranges`` (per point)."""
        o = self.origins if self.origins.shape[0] == 1 else self.origins[self.point_ray]
        return o + self.dirs[self.point_ray] * np.asarray(ranges, np.float64)[:, None]


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

    ``__init__`` picks a seeded share of the glossy returns (``tables``: the world's
    ``ghost.glossy_tables``; ``uniforms``: one per ray from the ghost generator, so one
    ray's fate never depends on which other rays returned) and starts casting their reflected beams (see ``World.start``: with the
    compiled Embree loop the frame's other work goes on meanwhile).
    ``finish`` turns the beams that found something into ghost points at total path
    a + b along the original beam, labelled as what the reflected beam found; glossy
    returns whose reflected beam finds nothing return nothing."""

    def __init__(self, world, tables, uniforms, origins, dirs, times, ret, rmax):
        self.world, self.rmax = world, rmax
        self.aim = ghost.aim(ret.valid, ret.surface, tables, uniforms, ret.dist, dirs,
                             ret.normals, origins)
        self.chosen = self.aim.chosen
        self.stats = {"glossy_hits": self.aim.glossy_hits, "ghosts": 0,
                      "bounce_rays": len(self.chosen)}
        self.pending = None
        if len(self.chosen):
            # Reflected beams start on a surface, inside its cluster box: the watertight
            # re-check would re-cast every one that escapes to the sky. A crack missed
            # by a ghost ray only loses one ghost point, so they are cast once.
            self.pending = world.start(self.aim.start, self.aim.r, times[self.chosen],
                                       rmax, watertight=False)

    def finish(self, ret):
        """Apply the bounces to ``ret``; returns (ghost rows, their last-leg
        directions, their mirrors' reflectivity)."""
        none = np.zeros(0, np.int64)
        if len(self.chosen) == 0:
            return none, np.zeros((0, 3)), np.zeros(0)
        b, body2, tri2, n2 = self.pending()
        fi, ret.ghost, last_leg, mirror = ghost.land(
            self.aim, b, tri2, n2, self.rmax, ret.valid, ret.dist, ret.normals,
            ret.surface, self.world.geometry.material_field("reflectivity"))
        g = self.chosen[fi]
        self.stats["ghosts"] = len(g)
        if len(g) == 0:
            ret.ghost = None
            return none, np.zeros((0, 3)), np.zeros(0)
        ret.surface[g] = self.world.surface_ids(body2[fi], tri2[fi])
        return g, last_leg, mirror


class _Subset:
    """The rays a frame casts (``scan_frame``'s ``rays``): ``self(a)`` takes them from a
    per-ray array of the whole pattern (a no-op when every ray is cast); ``order`` the
    pattern's trace order restricted to them."""

    def __init__(self, n, rows, order):
        self.rows, self.order = None, order
        if rows is None:
            return
        self.rows = np.asarray(rows, np.int64)
        if self.rows.ndim != 1 or (len(self.rows) and (self.rows.min() < 0
                                                        or self.rows.max() >= n)):
            raise ValueError(f"rays must be indices of the pattern's {n} rays")
        if order is not None:
            at = np.full(n, -1, np.int64)
            at[self.rows] = np.arange(len(self.rows))
            self.order = at[order]
            self.order = self.order[self.order >= 0]

    def __call__(self, a):
        if self.rows is None or a is None:
            return a
        return np.asarray(a).take(self.rows, axis=0)


def _inside_warnings(world, ray_obj, rows, back, in_air=None, min_hits=100, share=0.95):
    """Warn when nearly all points on an object land on the back of its faces: the
    sensor is inside it (fine for a tunnel or a room; a mistake for a solid object).
    ``ray_obj``: per ray, the object hit (index into ``world.geometry.objects``); per
    point: its ray (``rows``), whether it lies on a back face (``back``) and whether it
    is a false return from the air (``in_air``, or None: none is; those lie on no
    object, and are left out)."""
    if len(rows) < min_hits or np.count_nonzero(back) < min_hits:
        return []
    if in_air is not None:
        real = ~in_air
        rows, back = rows[real], back[real]
    obj = ray_obj.take(rows)
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


def scan_frame(scene, pattern, sensor_to_world, device, settings, caster_factory=None,
               frame=0, sensor="sensor", sensor_track=None, moving=(), keep_rays=False,
               fields=None, rays=None):
    """Scan one frame.

    scene            PreparedScene covering the sensor, or a SceneGeometry (world
                     coordinates), prepared here around the sensor with caster_factory
    pattern          ScanPattern (directions in the sensor frame, per-ray times)
    sensor_to_world  4x4 pose of the sensor at the start of the sweep
    device           the device's ``DeviceValues`` under ``settings``, resolved once by
                     whoever starts the scan (the session, the study's scanner); or its
                     ``DevicePreset``, resolved here (scripts, tests)
    settings         ``ScanSettings``
    sensor_track     optional Track of the sensor over the sweep (a moving sensor)
    moving           RigidBody / TimedScene bodies (moving and deforming objects)
    keep_rays        also return every ray and its first hit (``RayRecord``, for
                     ground truth); costs a copy of the hit objects and ranges
    fields           the ``POINT_DTYPE`` fields to assemble (None: all); a study that
                     only counts points asks for x, y and label, and the other
                     columns are never gathered (the points are the same)
    rays             indices of the pattern's rays to cast (None: all), for a still
                     sensor without footprints (a footprint needs its neighbours): each
                     ray returns what it returns in the whole frame (its random draws
                     are taken from the whole frame's), so the points are the whole
                     frame's points of those rays, in the same order. A study casts
                     only the rays whose points may fall in its region.
    Returns a ScanResult whose points follow ``POINT_DTYPE``; sensor-frame points are
    as the device reports them (each in the sensor frame at its own firing time).
    """
    return finished(scan_frame_started(scene, pattern, sensor_to_world, device, settings,
                                       caster_factory, frame, sensor, sensor_track, moving,
                                       keep_rays, fields, rays))


def scan_frame_started(scene, pattern, sensor_to_world, device, settings,
                       caster_factory=None, frame=0, sensor="sensor", sensor_track=None,
                       moving=(), keep_rays=False, fields=None, rays=None):
    """``scan_frame`` up to its cast, started: a generator whose one step is taken
    here (the rays aimed and cast on the compiled loop's threads, the random draws
    taken) and whose next (``finished``) waits for the cast and makes the points:
    the caller's work may go on meanwhile. The same ScanResult as ``scan_frame``."""
    freed_pages.keep_freed_pages()  # a frame's arrays reused, not faulted in anew
    dv = device if isinstance(device, DeviceValues) else device_values(device, settings)
    return started(_scan_frame(scene, pattern, sensor_to_world, dv, settings, caster_factory,
                               frame, sensor, sensor_track, moving, keep_rays, fields, rays))


def started(steps):
    """A generator of steps (``_scan_frame``, ``ScanSession._scan``) with its first step
    taken; ``finished`` takes the rest. Both with numpy's BLAS on one thread: OpenBLAS'
    spinning threads would slow the caster."""
    with blas_threads.single_threaded():
        next(steps)
    return steps


def finished(steps):
    """What a started generator of steps (``started``) returns, its steps left taken."""
    with blas_threads.single_threaded():
        try:
            while True:
                next(steps)
        except StopIteration as done:
            return done.value


def _scan_frame(scene, pattern, sensor_to_world, dv, settings, caster_factory, frame,
                sensor, sensor_track, moving, keep_rays=False, fields=None, ray_rows=None):
    """``scan_frame``'s steps, in the order their random draws are taken: a
    generator that pauses once, its cast under way."""
    t0 = time.perf_counter()
    s = settings
    rmin, rmax = dv.range_m
    n = len(pattern)  # every ray of the pattern draws its numbers (see ``rays``)
    substeps_used = None
    if s.motion == "substeps":
        substeps_used = s.substeps or adaptive_substeps(moving, sensor_track,
                                                        dv.motion_tolerance_m)
    tscene = effective_times(pattern.times, pattern.period, s.motion, substeps_used)
    aim = _Aim.of(pattern, sensor_to_world, sensor_track, tscene,
                  scene.centre if isinstance(scene, PreparedScene) else None)
    pick = _Subset(n, ray_rows, pattern.trace_order)
    if pick.rows is not None:
        if dv.beam is not None or aim.poses.shape[0] != 1:
            raise ValueError("scan_frame(rays=...) is for a still sensor without beam "
                             "footprints (a footprint needs its neighbours' rays)")
        aim = aim.subset(pick)
    scene = _prepared(scene, aim, rmax, caster_factory)
    world = World(scene, list(moving))
    warnings = list(scene.warnings) + _empty_scene_warnings(scene, moving, rmax)

    # A sensor that does not move casts the same rays into the same static scene every
    # frame: the static part is cast once and reused (see PreparedScene.cast). A
    # driving one's origins are new every frame (read-only too, see
    # track_set.positions_at): nothing to keep.
    reused = scene.reused
    still = sensor_track is None or sensor_track.is_static
    pending = world.start(aim.origins, aim.dirs, aim.times, rmax, order=aim.order,
                          reuse=pick.rows is None and still)
    rng, ghost_rng = effects.scan_rng(s.seed, sensor, frame)
    draws, glossy, glossy_u = _draws(rng, ghost_rng, n, pick, s, dv, world)
    before = time.perf_counter() - t0  # the frame's own time: not the caller's meanwhile
    yield  # the cast under way: the caller's own work goes on
    t0 = time.perf_counter() - before

    dist, body, tri, normals = pending()
    reused = scene.reused > reused
    valid, surface = world.returns(dist, body, tri, rmin, rmax)
    ret = Returns(valid, dist, surface, normals)
    first_hit = _first_hits(ret, tri, dist, rmax) if keep_rays else None
    # Rays next to a depth edge cast their beam's sub-rays (before ghosts change rows)
    sub = footprint.SubRays(dv.beam, world, pattern, aim.origins, aim.dirs, aim.times, ret,
                            tri, rmax) if dv.beam is not None else None
    bounces = _Bounces(world, glossy, glossy_u, aim.origins, aim.dirs, aim.times, ret, rmax) \
        if glossy_u is not None and ret.valid.any() else None

    g = world.geometry
    medium_rows, medium_dist = _air_returns(dv.weather, draws, tri, dist, rmin, rmax)
    refl = g.material_field("reflectivity").astype(np.float64)
    rows, ghost_dot, ghost_int, stats = _ghosts(bounces, ret, refl, dv.attenuation_per_m)
    beam_echoes = _echoes(sub, ret, aim.dirs, bounces, rows, medium_rows, refl, dv, draws,
                          rng, rmin, rmax, stats)
    hits = Hits(ret.dist, ret.valid, ret.surface, ret.normals, ret.ghost, rows, ghost_dot,
                ghost_int, refl, g.object_field("label"), g.object_field("instance"),
                medium_rows, medium_dist)
    rays = Rays(aim.dirs, aim.origins, aim.columns, aim.channels, aim.ray_times)
    pts, idx, back = _points(hits, rays, draws, _effects(dv), s, fields, beam_echoes)
    if aim.beam_origins is not None and s.frame_space != "world":
        _from_beam_origins(pts, aim.beam_origins, idx)
    in_air = _air_stats(dv.weather, medium_rows, len(aim.dirs), idx, stats)
    warnings += _inside_warnings(world, ret.surface[:, 0], idx, back, in_air)
    stats["moving_bodies"] = len(moving)
    stats["substeps_used"] = substeps_used
    stats["static_cast_reused"] = reused
    record = None
    if keep_rays:
        record = RayRecord(aim.origins, aim.dirs, aim.ray_times, first_hit[0], first_hit[1],
                           idx, list(g.objects))
    return ScanResult(pts, len(aim.dirs), len(scene.triangles), time.perf_counter() - t0,
                      warnings, stats, record)


def _from_beam_origins(pts, beam_origins, idx):
    """Sensor-frame points moved from the sensor origin to their beams' own origins
    (``beam_origins``: (rays, 3) in the sensor frame; ``idx``: each point's ray): the
    assembled points are range x sensor-frame direction."""
    for k, f in enumerate("xyz"):
        if f in pts.dtype.names:
            pts[f] += beam_origins[idx, k]


def _prepared(scene, aim, rmax, caster_factory):
    """``scene`` as a ``PreparedScene`` that covers every pose of the sweep out to
    ``rmax``: prepared here from a ``SceneGeometry``, or checked (against every ray's
    origin without beam offsets: the poses, repeated)."""
    if not isinstance(scene, PreparedScene):
        poses = aim.poses
        return PreparedScene(scene, poses.mean(axis=0),
                             rmax + np.ptp(poses, axis=0).max(initial=0.0), caster_factory)
    if not scene.covers(aim.pose_points(), rmax):
        raise SceneError("the prepared scene does not cover this sensor's range: prepare "
                         "it around the sensor with a reach of at least its range")
    return scene


def _empty_scene_warnings(scene, moving, rmax):
    if scene.geometry.triangle_count == 0 and not moving:
        return ["the scene has no geometry to scan"]
    if len(scene.triangles) == 0 and not moving:
        return [f"no geometry within {rmax:g} m of the sensor"]
    return []


def _draws(rng, ghost_rng, n, pick, s, dv, world):
    """Every random number of the effects, drawn per ray, not per hit, so a ray's draws
    never depend on which other rays returned (ghosting or moving objects change only
    their own rays); drawn while the rays are cast (the compiled loop's threads cast
    meanwhile). Returns (Draws, the world's glossy tables or None, the ghost
    generator's uniforms or None)."""
    draws = Draws(noise=pick(effects.range_noise(rng, n, dv.noise_sigma_m)) if s.noise
                  else None)
    if s.dropout:
        draws.general, draws.low = (pick(u) for u in effects.dropout_draws(
            rng, n, dv.dropout.general_rate, dv.dropout.intensity_limit,
            dv.dropout.intensity_zero))
    # Drawn after noise and dropout, and only when used: a frame without datasheet
    # figures and weather draws what it drew before the LiDAR equation.
    if dv.detection is not None:
        draws.detect = pick(rng.random(n))
    if dv.weather is not None:
        draws.medium, draws.medium_range = pick(rng.random(n)), pick(rng.random(n))
    # Which glossy returns send a ghost: the ghost generator's own uniforms, drawn only
    # where something is glossy (a material, or an object's label).
    glossy = ghost.glossy_tables(world.geometry, ghost.glossy_labels()) if s.ghosting \
        else None
    glossy_u = pick(ghost_rng.random(n)) \
        if glossy is not None and (glossy[0].any() or glossy[1].any()) else None
    return draws, glossy, glossy_u


def _first_hits(ret, tri, dist, rmax):
    """(object, range) of each ray's first hit within range, before ghosts relabel the
    glossy rays (for ground truth)."""
    hit = (tri >= 0) & (dist <= rmax)
    return (np.where(hit, ret.surface[:, 0], -1).astype(np.int32), np.where(hit, dist, np.inf))


def _air_returns(air, draws, tri, dist, rmin, rmax):
    """The rays that return from the air (fog, rain, snow) and at what range: beyond
    the blind zone (at least weather.OVERLAP_M), nearer than the first surface the ray
    meets (a mirror, not its ghost): the air beyond sends nothing."""
    none = np.zeros(0, np.int64), np.zeros(0)
    if air is None:
        return none
    r_near = max(float(rmin), weather.OVERLAP_M)
    if r_near >= rmax:
        return none
    return weather.false_returns(air.alpha, draws.medium, draws.medium_range, tri >= 0, dist,
                                 r_near, rmax)


def _ghosts(bounces, ret, refl, atten):
    """The ghost bounces finished: (ghost rows, the cosine and CARLA intensity of each
    ghost's last leg, the frame's stats so far)."""
    rows, ghost_dot, ghost_int = np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    if bounces is None:
        return rows, ghost_dot, ghost_int, {"glossy_hits": 0, "ghosts": 0, "bounce_rays": 0}
    rows, last_leg, mirror = bounces.finish(ret)
    if len(rows):
        ghost_dot = row_dot(last_leg, ret.normals.take(rows, axis=0))
        ghost_int = mirror * effects.intensity(refl[ret.surface[rows, 1]], np.abs(ghost_dot),
                                               ret.dist[rows], atten)
    return rows, ghost_dot, ghost_int, bounces.stats


def _echoes(sub, ret, dirs, bounces, rows, medium_rows, refl, dv, draws, rng, rmin, rmax,
            stats):
    """A footprint's echoes (``echoes.resolve``) of the rays whose sub-rays saw more than
    their centre, or None; their counts go into ``stats``."""
    if sub is None:
        return None
    if not sub.count:
        stats.update(footprint_rays=0, footprint_sub_rays=sub.cast)
        return None
    # Drawn last and only here: the key of the detection uniforms of echoes that do
    # not hold the centre ray (echoes._uniforms)
    key = int(rng.integers(0, 2 ** 63)) if dv.detection is not None else 0
    skip = np.concatenate([bounces.chosen if bounces is not None else rows, medium_rows])
    beam_echoes, fstats = echoes.resolve(
        sub, ret, dirs, skip, refl, dv.detection, draws.detect, key,
        0.0 if dv.weather is None else dv.weather.alpha, dv.attenuation_per_m, rmin, rmax)
    stats.update(fstats)
    return beam_echoes


def _effects(dv):
    model, air = dv.detection, dv.weather
    return Effects(dv.dropout.general_rate, dv.dropout.intensity_limit,
                   dv.dropout.intensity_zero, dv.attenuation_per_m, model,
                   "carla" if model is None else model.intensity,
                   0.0 if air is None else air.alpha)


def _points(hits, rays, draws, fx, s, fields, beam_echoes):
    """The per-hit stage: (points, the ray of each point, which were hit from behind);
    a footprint's second echoes next to their pulse's first."""
    extra = None
    if beam_echoes is not None:
        hits, extra = footprint.split(hits, rays, draws, beam_echoes)
    pts, idx, back = assemble(hits, rays, draws, fx, s.frame_space, fields)
    if extra is not None:
        pts, idx, back = footprint.merge((pts, idx, back),
                                         assemble(*extra, fx, s.frame_space, fields),
                                         beam_echoes.extra_parent)
    return pts, idx, back


def _air_stats(air, medium_rows, n_rays, idx, stats):
    """Which points came from the air (they lie on no object; None when none can), and
    their count in ``stats``."""
    if len(medium_rows):
        medium = np.zeros(n_rays, bool)
        medium[medium_rows] = True
        in_air = medium.take(idx)
        stats["weather_returns"] = int(np.count_nonzero(in_air))
        return in_air
    if air is not None:
        stats["weather_returns"] = 0
    return None
