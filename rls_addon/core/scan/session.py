"""A scan session: one frame of one sensor at a time from a scene source, keeping what
can be kept between frames and sensors.

- Static geometry is built into a ray-casting structure once and reused while it is
  unchanged (the same meshes, matrices, materials and labels; else its digest decides).
- A lidar that may move (is animated) gets its static scene prepared around grid
  points ``DRIVING_SLACK`` of its range apart, that much wider: a driving lidar's
  frames share one built structure per grid cell instead of one per frame. What is
  prepared depends on the frame alone, never on the frames before: a run split over
  workers writes the same bytes as a whole one.
- Each group of rigidly moving objects keeps its own structure; deforming objects are
  rebuilt per sub-step.
"""

import dataclasses

import numpy as np

from ..native import blas_threads
from ..world.bodies import PreparedScene, RigidBodies, TimedScene
from ..physics.detection import detection_info
from ..physics.footprint import footprint_info
from .frame import finished, scan_frame_started, sensor_frame, started
from ..output.ground_truth import box_dicts, object_boxes
from ..output.io.behind import Later
from ..scene.geometry import nonfinite_warning
from ..scene.instances import (bodies_key, object_table, static_key, without_nonfinite,
                               world_geometry)
from ..labels import DEFAULT_LABELS
from ..scene.motion import pose_knots, rigid
from .device_values import device_values
from .settings import scan_pattern
from .sweep import SweepMotion, classify, substep_count

MOVER_MARGIN_M = 10.0  # objects this far beyond the range at the sweep start may drive in
DRIVING_SLACK = 0.25
KEEP_PREPARED = 16     # prepared scenes and body groups kept per session


class ScanSession:
    """Scans frames of sensors from scene sources with one ray-casting backend
    (``caster_factory``, see ``casting``)."""

    def __init__(self, caster_factory, kept_sweeps=None):
        self.caster_factory = caster_factory
        # a KeptSweeps (kept_sweeps.py): a still sensor's sampled sweeps kept between
        # scans; whoever hands it in clears it when the scene changes (live coverage)
        self.kept_sweeps = kept_sweeps
        self._prepared = {}
        self._bodies = {}
        self.builds = 0
        self._last_read = None        # (read, instances, skipped, objects): _finite
        self._last_static_key = None  # ((read, selection), key): _static_key

    def _cached(self, store, key, make):
        item = store.get(key)
        if item is None:
            if len(store) >= KEEP_PREPARED:  # bounded: a moving sensor keeps seeing new geometry
                store.pop(next(iter(store)))
            item = store[key] = make()
            self.builds += 1
        return item

    def prepared(self, geometry, centre, reach, key=None):
        """The ``PreparedScene`` of ``geometry`` (or of ``geometry()``, a function that
        builds it, when ``key`` identifies it without its digest)."""
        if key is None:
            geometry = geometry() if callable(geometry) else geometry
            key = geometry.fingerprint()
        key = (key, tuple(np.round(centre, 9)), reach)
        return self._cached(self._prepared, key, lambda: PreparedScene(
            geometry() if callable(geometry) else geometry, centre, reach, self.caster_factory))

    @staticmethod
    def anchor(centre, rmax, may_move):
        """(centre, reach) to prepare a sensor's static scene for, from where it is now
        alone (no history, so a run split into pieces prepares what a whole run does):
        a sensor that cannot move, where it stands with its range; one that may (it is
        animated), around the point of a grid of ``DRIVING_SLACK`` of its range nearest
        to it, reaching that much farther, so its frames share one built scene while it
        drives through a cell."""
        if not may_move:
            return centre, rmax
        cell = DRIVING_SLACK * rmax
        anchor = np.round(np.asarray(centre, np.float64) / cell) * cell
        return anchor, rmax * (1.0 + DRIVING_SLACK) + MOVER_MARGIN_M

    def scan(self, source, sensor, preset, settings, frame, object_classes=None, values=None,
             boxes_later=False):
        """Scan ``frame`` (the source is already at it) of sensor ``sensor`` with device
        ``preset`` and ``ScanSettings`` ``settings``. Returns (ScanResult, info dict
        for the sidecar). ``object_classes`` (label ids): ground-truth boxes of the
        objects of these classes go into the info (``ground_truth``). ``values``: the
        preset's ``DeviceValues`` under ``settings`` when the caller has them (a run
        resolves them once per sensor), else resolved here; either way once per scan,
        and what the frame, the sub-steps, the boxes and the sidecar read.
        ``boxes_later``: the info's ``objects`` are a ``behind.Later`` that works them
        out (the same boxes) when the frame's files are written, for a writer that
        writes behind the scan (``works_out_later``).

        All of it with numpy's BLAS on one thread (``blas_threads.single_threaded``, as
        the frame itself): the sweep's, the bodies' and the boxes' many small products
        and inverses cost 3x as much on OpenBLAS' threads (a 4x4 inverse 80 us
        against 25 us here, and far more when other work shares the cores)."""
        return finished(self.scan_started(source, sensor, preset, settings, frame,
                                          object_classes, values, boxes_later))

    def scan_started(self, source, sensor, preset, settings, frame, object_classes=None,
                     values=None, boxes_later=False):
        """``scan``, started: the scene read from ``source`` and the frame's cast under
        way (``frame.scan_frame_started``); returns a generator whose remaining steps
        (``frame.finished``) give ``scan``'s (ScanResult, info). Until then the source
        may move on (another frame's scan): nothing left reads it."""
        if values is None:
            values = device_values(preset, settings)
        return started(self._scan(source, sensor, preset, settings, values, frame,
                                  object_classes, boxes_later))

    def _scan(self, source, sensor, preset, settings, values, frame, object_classes,
              boxes_later=False):
        pose = source.sensor_pose(sensor)
        frame_pose = sensor_frame(pose, sensor)  # its sensor frame (no scale): the sidecar's
        rmax = values.max_range_m
        centre = pose[:3, 3]
        anchor, reach = self.anchor(centre, rmax, source.sensor_may_move(sensor))
        read = source.read(anchor, reach + MOVER_MARGIN_M, {sensor})
        # skipped: triangles with NaN or infinite coordinates, per object
        instances, skipped, objects = self._finite(read)
        materials = read.materials
        motion = SweepMotion()
        if settings.motion != "snapshot":
            mobility = source.mobility(instances, sensor)
            with self._sweep(source, frame, preset.period, mobility) as sweep:
                motion = self._classify(sweep, preset.period, instances, mobility, sensor)
                n_used, substeps = self._substep_counts(values.motion_tolerance_m, settings,
                                                        instances, motion)
                moving = self._bodies_of(sweep, preset.period, instances, objects, materials,
                                         motion, substeps, skipped)
        else:
            n_used, substeps, moving = None, {}, []
        # "substeps" motion with N = 0: the sweep is cast with the N chosen above.
        cast_settings = settings if n_used is None else dataclasses.replace(settings,
                                                                            substeps=n_used)
        track = motion.sensor
        if track is not None:
            sensor_frame(track.matrices, sensor)  # a scale that reaches zero in the sweep
            sweep_path = track.matrices[:, :3, 3]
            if np.linalg.norm(sweep_path - anchor, axis=1).max() + rmax > reach:
                # The sweep leaves the anchored scene: one around this sweep alone.
                anchor = centre
                reach = rmax + float(np.linalg.norm(sweep_path - centre, axis=1).max())
        static_sel = set(range(len(instances))) - motion.moved
        # Joined (and digested) only when the session has not built it before.
        scene = self.prepared(
            lambda: world_geometry(instances, objects, materials, select=static_sel), anchor,
            reach, self._static_key(read, instances, objects, materials, static_sel))
        classes = set(object_classes or ())
        boxes = bool(classes) and any(i.label in classes for i in instances)
        frame_steps = scan_frame_started(scene, scan_pattern(preset, settings, frame), pose,
                                         values, cast_settings, frame=frame, sensor=sensor,
                                         sensor_track=track, moving=moving, keep_rays=boxes)
        yield  # the cast under way
        result = finished(frame_steps)
        if skipped:
            result.warnings.insert(0, nonfinite_warning(skipped))
        result.warnings[:0] = read.warnings
        info = self._info(preset, settings, values, sensor, frame, frame_pose, motion,
                          instances, substeps, n_used, objects, scene, result, read)
        info.update(sensor_pose_record(frame_pose, track, preset.period))
        if object_classes is not None:
            info["objects"] = []
            if boxes:
                # what the boxes read of the result: its points and rays (dropped below)
                seen = dataclasses.replace(result)
                info["objects"] = _boxes(
                    instances, objects, motion.tracks if settings.motion != "snapshot" else {},
                    classes, seen, _pose_function(frame_pose, track), rmax,
                    values.noise_sigma_m, preset.period, later=boxes_later)
            info["object_classes"] = sorted(classes)
        result.rays_cast = None  # large; the boxes hold what was wanted from it
        return result, info

    def _finite(self, read):
        """(the read's instances without their non-finite triangles, how many each lost,
        the object table): kept for the same read, which a source gives again while
        nothing in an unedited file but the sensors can change (``skipped`` a copy
        each time: a frame adds its deforming sub-steps' to it)."""
        kept = self._last_read
        if kept is not None and kept[0] is read:
            return kept[1], dict(kept[2]), kept[3]
        skipped = {}
        instances = without_nonfinite(read.instances, skipped)
        objects = object_table(instances)
        self._last_read = (read, instances, dict(skipped), objects)
        self._last_static_key = None
        return instances, skipped, objects

    def _static_key(self, read, instances, objects, materials, select):
        """``static_key`` of the static part ``select``, kept for the same read and
        selection (see ``_finite``)."""
        key = (read, frozenset(select))
        kept = self._last_static_key
        if kept is not None and kept[0][0] is read and kept[0][1] == key[1]:
            return kept[1]
        got = static_key(instances, objects, materials, select)
        self._last_static_key = (key, got)
        return got

    def _sweep(self, source, frame, period, mobility):
        """The sweep to sample: the source's, or for a sensor that cannot move the
        states kept since the last scan of this frame (``kept_sweeps``)."""
        if self.kept_sweeps is None or mobility.sensor_moves:
            return source.sweep(frame, period)
        return self.kept_sweeps.sweep(source, frame, period)

    @staticmethod
    def _classify(sweep, period, instances, mobility, sensor):
        """``sweep.classify``; a kept sweep gives back its last classification of the
        same objects (``kept_sweeps``)."""
        def fresh():
            return classify(sweep, period, instances, mobility, sensor)

        kept = getattr(sweep, "motion", None)
        return fresh() if kept is None else kept(instances, mobility, fresh)

    @staticmethod
    def _substep_counts(tol, settings, instances, motion):
        """(N of "substeps" motion or None, {deforming instance index: N}). Both follow
        ``settings.substeps``: fixed, or (0) chosen from how far things move within
        ``tol`` (m, the device's motion tolerance)."""
        n_used = None
        if settings.motion == "substeps":
            n_used = substep_count(motion.max_travel(instances), tol, settings.substeps)
        deforming = {k: n_used if n_used is not None else substep_count(m, tol, settings.substeps)
                     for k, m in motion.deforming}
        return n_used, deforming

    def _bodies_of(self, sweep, period, instances, objects, materials, motion, substeps,
                   skipped):
        """The moving bodies of a sweep: each deforming instance's sub-steps, then one
        group of the rigid ones (kept by the session while their meshes are the same).
        ``skipped``: see ``_substeps``."""
        bodies = []
        for k, _ in motion.deforming:
            bodies += self._substeps(sweep, period, instances[k], k, objects, materials,
                                     substeps[k], skipped)
        if motion.rigid:
            def local(k):
                return world_geometry(instances, objects, materials, select={k}, local=True)

            # Kept while what was read is the same (their meshes' ids), else while their
            # digests are: their geometry is joined only when the group is new.
            key = bodies_key(instances, objects, materials, [k for k, _ in motion.rigid])
            if key is None:
                rigid = [(instances[k].key, local(k)) for k, _ in motion.rigid]
                key = tuple((name, geometry.fingerprint()) for name, geometry in rigid)
                parts = [g for _, g in rigid]
            else:
                parts = None
            group = self._cached(self._bodies, key, lambda: RigidBodies(
                [(g, tr) for g, (_, tr) in zip(parts or [local(k) for k, _ in motion.rigid],
                                               motion.rigid)], self.caster_factory))
            group.tracks = [tr for _, tr in motion.rigid]  # this sweep's motion
            bodies.append(group)
        return bodies

    def _substeps(self, sweep, period, inst, k, objects, materials, n, skipped):
        """TimedScenes of a deforming instance at the middle of each of n sub-sweeps
        (its triangles with NaN or infinite coordinates left out, and counted in
        ``skipped`` once: the most of any sub-step)."""
        out = []
        step = period / n
        for j in range(n):
            snap = sweep.instance_at((j + 0.5) * step, inst)
            if snap is not None:
                bad = {}
                snap = (without_nonfinite([snap], bad) or [None])[0]
                if bad:
                    skipped[inst.key] = max(skipped.get(inst.key, 0), bad[inst.key])
            if snap is None:
                continue
            geom = world_geometry([snap], [objects[k]], materials)
            scene = PreparedScene(geom, snap.matrix[:3, 3], np.inf, self.caster_factory)
            self.builds += 1
            t1 = (j + 1) * step if j < n - 1 else np.inf
            out.append(TimedScene(scene, j * step if j else -np.inf, t1))
        return out

    @staticmethod
    def _info(preset, settings, values, sensor, frame, pose, motion, instances, substeps,
              n_used, objects, scene, result, read):
        keys = {k: instances[k].key for k in range(len(instances))}
        summary = {"rigid": [keys[k] for k, _ in motion.rigid],
                   "deforming": [keys[k] for k, _ in motion.deforming],
                   "samples": motion.samples,
                   "substeps": {keys[k]: n for k, n in substeps.items()},
                   "sensor_moves": motion.sensor is not None}
        return {
            "device": {"id": preset.id, "name": preset.name, "source": preset.source,
                       "detection": detection_info(preset, settings),
                       "beam": footprint_info(preset, settings)},
            **_channels(preset),
            "sensor": sensor,
            "frame": frame,
            "frame_space": settings.frame_space,
            "sensor_to_world": pose.tolist(),
            "seed": settings.seed,
            "effects": dict(effects_info(preset, settings, values), substeps_used=n_used),
            "motion": summary,
            "labels": {str(o.instance): {"object": o.name, "label": o.label} for o in objects},
            "backend": scene.backend,
            "rays": result.rays,
            "points": int(len(result.points)),
            "triangles_cast": result.triangles,
            "objects_read": read.stats.get("objects", len(instances)),
            "objects_culled_by_range": read.stats.get("culled_by_range", 0),
            "ghosts": result.stats.get("ghosts", 0),
            "weather_returns": result.stats.get("weather_returns", 0),
            "footprint": {k: result.stats.get(k, 0) for k in (
                "footprint_rays", "footprint_changed_rays", "multi_echo_rays",
                "second_returns", "mixed_points")},
            "warnings": result.warnings,
        }


def effects_info(preset, settings, values):
    """The sidecar's ``effects``: what a scan's settings made of the device (``values``,
    its ``DeviceValues`` under them), all but the sub-steps a frame chose
    (``substeps_used``)."""
    return {"noise": settings.noise, "dropout": settings.dropout,
            "range_m": list(values.range_m), "noise_sigma_m": values.noise_sigma_m,
            "motion": settings.motion, "substeps": settings.substeps,
            "sweep_start_deg": settings.sweep_start_deg, "ghosting": settings.ghosting,
            "detection": settings.detection, "weather": _weather_info(values),
            "footprint": settings.footprint, "return_mode": settings.return_mode,
            "rotation_hz": preset.frequency_hz if preset.family == "spinning" else None,
            "lidar_mode": _lidar_mode(preset, settings)}


def _lidar_mode(preset, settings):
    """The lidar mode a scan ran in (None: the device has none)."""
    modes = getattr(preset, "modes", None)
    return settings.lidar_mode or (modes.default_lidar_mode if modes else None)


def settings_record(preset, settings, values):
    """The settings of a scan as its sidecar states them (``_info``), by name: the
    device, the seed, the frame space and every effect (``values``: the preset's
    ``DeviceValues`` under ``settings``). A resumed run keeps a frame only when its
    sidecar states the same (``io.sidecar.settings_differences``)."""
    return {"device": preset.id, "seed": settings.seed, "frame_space": settings.frame_space,
            **effects_info(preset, settings, values)}


def _weather_info(values):
    """The sidecar's weather: None (clear) or the spec, extinction coefficient and false
    return model (``weather.Weather.to_dict``)."""
    return None if values.weather is None else values.weather.to_dict()


def _channels(preset):
    """A spinning device's channel-table elevations (degrees, by ring), for readers
    that number rings by elevation (io.point_types)."""
    if preset.family != "spinning":
        return {}
    from ..device.presets import spinning_elevations_offsets

    return {"channel_elevations_deg": [float(e) for e in spinning_elevations_offsets(preset)[0]]}


def _boxes(*args, later=False):
    """``box_dicts`` of ``object_boxes(*args)``, or (``later``) a ``Later`` that works
    them out on the thread that asks, with numpy's BLAS on one thread there too."""
    if not later:
        return box_dicts(object_boxes(*args))

    def work():
        with blas_threads.single_threaded():
            return box_dicts(object_boxes(*args))

    return Later(work)


def _pose_function(pose, track):
    """f(times) -> (N, 4, 4) poses of the sensor frame: the track's, or the still
    ``pose`` (rigid already)."""
    if track is None:
        return lambda t: np.broadcast_to(pose, (len(np.atleast_1d(t)), 4, 4))
    return lambda t: rigid(track.at(t))


def sensor_pose_record(pose, track, period):
    """The sidecar's poses of the sensor frame (the LiDAR object's matrix without its
    scale and shear: ``frame.sensor_frame``; ``pose`` is rigid already): at the sweep
    start and end, and for a moving sensor knots that give its pose at any firing time
    within half a millimetre (``poses_at``: linear translation, slerp rotation)."""
    if track is None:
        return {"sensor_pose_start": pose.tolist(), "sensor_pose_end": pose.tolist(),
                "sensor_moves": False, "label_names": {str(k): v for k, v in DEFAULT_LABELS.items()}}
    times, mats = pose_knots(track)
    # the knots' first and last are the poses at the sweep's start and end when the
    # track spans the sweep (as sampled): the same evaluation
    start = mats[0] if times[0] == 0.0 else rigid(track.at([0.0])[0])
    end = mats[-1] if times[-1] == period else rigid(track.at([period])[0])
    return {"sensor_pose_start": start.tolist(),
            "sensor_pose_end": end.tolist(), "sensor_moves": True,
            "sensor_poses": {"times_s": times.tolist(), "matrices": mats.tolist(),
                             "interpolation": "between knots: translation linear, rotation "
                                              "by quaternion slerp; within 0.5 mm of the "
                                              "sensor's path"},
            "label_names": {str(k): v for k, v in DEFAULT_LABELS.items()}}

