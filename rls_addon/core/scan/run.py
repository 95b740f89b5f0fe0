"""One scan run, frames x sensors, behind every entry point (the UI's scan operators,
``rls scan``, scripts): sessions that keep prepared scenes, per-frame seeds (from
(seed, sensor, frame), see ``effects.scan_rng``), files and sidecars, resume, cancel
and progress.

Blender comes in through small interfaces: a scene source (``source.SceneSource``),
a caster factory (``casting.caster_factory``), a writer (``io.writer.CloudWriter``
or anything with its ``check``/``existing``/``write``) and callbacks for progress,
results (previews) and cancelling. A run advances one (frame, sensor) step per
``step()`` call, so a modal operator can run it between UI events and a script or the
command line can ``run()`` it straight through.
"""

import gc
import time
from collections import namedtuple
from dataclasses import dataclass, field
from typing import Protocol

from ..casting import caster_factory
from ..errors import SceneError
from ..scene.instances import check_ids
from ..scene.traffic_keys import check_keyed, source_span
from ..labels import label_id, label_name
from ..output.io.fields import float32_warning
from . import run_files
from .device_values import device_values
from .frame import finished
from .session import ScanSession, settings_record


@dataclass(frozen=True)
class SensorJob:
    """One sensor of a run: its name in the scene, its settings, its device."""

    name: str
    settings: object   # settings.LidarSettings
    preset: object     # presets.DevicePreset


@dataclass
class Step:
    """What one (frame, sensor) step did, as progress callbacks see it."""

    frame: int
    sensor: str
    done: int              # steps done so far, this one included
    total: int
    points: int
    seconds: float         # the scan's own time (0 for a resumed step)
    path: str = None       # the cloud written or kept (None without a writer)
    resumed: bool = False  # kept from an earlier run
    eta_s: float = 0.0     # estimate of the time left
    warnings: list = field(default_factory=list)
    # the step's wall time and its parts (``STEP_PARTS``), the scan's own among them
    wall_s: float = 0.0
    parts: dict = field(default_factory=dict)


# A step whose scan started (``ScanRun.step``): its remaining ``steps`` (a generator,
# ``frame.finished``) and when its parts began.
_Started = namedtuple("_Started", "frame job told steps t_step t_scan t_started")


# What a step's wall time is spent on, in order: Blender setting the frame (animation,
# drivers, modifiers), reading what the sensor may see and its ground-truth boxes, the
# scan itself (casting, effects, points), writing (or queueing for the writer thread)
# and showing the preview.
STEP_PARTS = ("frame", "scene", "scan", "write")


class Writer(Protocol):
    shardable: bool  # pieces of a run may write on several workers
    # what ``finish`` writes, as a subject with its verb ("... is"), for the line of a
    # run that stopped before it (optional: none said)
    written_at_end: str

    def path(self, sensor: str, output, frame: int): ...

    def planned_files(self, sensor: str, output, frame: int) -> list:
        """Every file a scan of (sensor, frame) writes (its path first)."""

    def incomplete(self, sensor: str, output, frame: int) -> list:
        """Files a write of (sensor, frame) cut short by a killed process left behind."""

    def check(self, sensor: str, output, frame: int) -> None: ...

    def existing(self, sensor: str, output, frame: int, settings: dict = None) -> int | None:
        """The point count of an earlier output to keep (resuming), else None; a writer
        that can compares ``settings`` (``session.settings_record``) with its files'."""

    def kept_labels(self, sensor: str, output, frame: int) -> dict:
        """Optional: the ``labels`` (instance id -> object and label) an output kept by
        ``existing`` was written with, so that a resumed run's instance table holds the
        objects of the frames it kept, as an uninterrupted run's does."""

    def write(self, sensor: str, output, frame: int, points, info: dict): ...

    def finish(self, run) -> None:
        """After the last step of a run that was not cancelled (run-level files)."""

    def abort(self) -> None:
        """The run ended early: drop what only a complete run may leave."""

    def flush(self) -> None:
        """Wait for files still being written (a writer that writes in the background);
        called when a run or a piece of one ends."""


class ScanRun:
    """Scan ``frames`` x ``sensors`` (``SensorJob``) of ``source``.

    writer     where clouds go (None: scan only, e.g. a preview)
    progress   called with a ``Step`` after every step
    on_result  called with (job, frame, ScanResult, info) after every scan (previews)
    cancelled  a function polled before every scan (after the frame is set, so a
               frame-change handler may ask to stop); True ends the run there
    factory    ``casting.caster_factory``-like: name -> (backend class, notice)
    sessions   {backend name: ScanSession} to keep prepared scenes in over runs (a
               worker's pieces of a sharded run)
    piece      True for one piece of a sharded run: the run-level files are written by
               whoever assembles the pieces (``absorb``), not here

    A run can also be spread over workers (``commands.distribute``): ``pieces`` splits
    its plan, each piece runs as a run of its own on a worker, and ``absorb`` takes
    their steps back in plan order, so the summary and the run-level files are what a
    whole run gives; seeds come from (seed, sensor, frame), so the clouds are too.
    """

    def __init__(self, source, sensors, frames, writer=None, progress=None, on_result=None,
                 cancelled=None, factory=caster_factory, sessions=None, piece=False):
        if not sensors:
            raise SceneError(f"scene '{source.name}' has no LiDAR objects "
                             f"(add one with Add > LiDAR)")
        if not frames:
            raise SceneError("no frames to scan (the frame range is empty)")
        check_keyed(frames, source_span(source))
        self.source, self.sensors, self.frames = source, list(sensors), list(frames)
        self.writer, self.progress, self.on_result = writer, progress, on_result
        self._cancelled = cancelled or (lambda: False)
        self.plan = [(f, job) for f in self.frames for job in self.sensors]
        if writer is not None:  # fail before scanning anything
            run_files.distinct_outputs(self.plan, writer)
            for job in self.sensors:
                writer.check(job.name, job.settings.output, self.frames[0])
            if not piece and not (getattr(writer, "resume", False)
                                  or getattr(writer, "overwrite", False)):
                self.free_outputs()
            if not piece and (getattr(writer, "resume", False) or getattr(writer, "overwrite", False)):
                self.remove_leftovers()  # what a killed earlier run of these outputs left
        # each sensor's device after its settings, resolved once for the run
        self._values = {j.name: device_values(j.preset, j.settings.scan) for j in self.sensors}
        self._records = {j.name: settings_record(j.preset, j.settings.scan, self._values[j.name])
                         for j in self.sensors}
        self._told_stale = set()  # sensors whose files of other settings were reported
        self.sessions, self.notices = ({} if sessions is None else sessions), []
        if writer is not None and not piece and hasattr(writer, "orphan_notices"):
            self.notices += writer.orphan_notices([(j.name, j.settings.output, f)
                                                   for f, j in self.plan])
        self.piece = piece
        for job in self.sensors:
            backend = job.settings.backend
            if backend not in self.sessions:
                backend_cls, notice = factory(backend)
                self.sessions[backend] = ScanSession(backend_cls)
                if notice and notice not in self.notices:
                    self.notices.append(notice)
        self.original_frame = source.current_frame()
        self.index = 0
        self.scanned = self.resumed = self.points = 0
        self.paths, self.outputs, self.frames_done = [], [], []
        self.warnings = list(self.notices)
        self.cancelled = False
        self.last = None
        self.id_map = {}  # instance id -> {object name: label id}, over the whole run
        self._frame_set = None
        self._next = 0          # the plan's next step to start (index: steps ended)
        self._pending = None    # a started step whose scan is under way (step)
        self._scan_time = 0.0
        self._budget = run_files.disk_budget(self.plan, writer) \
            if writer is not None and not piece else None
        self.t0 = time.perf_counter()

    @property
    def total(self):
        return len(self.plan)

    @property
    def finished(self):
        return self.cancelled or self.index >= len(self.plan)

    @property
    def structure_builds(self):
        return sum(s.builds for s in self.sessions.values())

    def eta(self):
        """Seconds left, estimated from the steps scanned so far."""
        if not self.scanned:
            return 0.0
        return self._scan_time / self.scanned * (self.total - self.index)

    def status(self):
        frame, job = self.plan[min(self.index, len(self.plan) - 1)]
        return (f"LiDAR scan: frame {frame} ({job.name}), {self.index}/{self.total} done, "
                f"about {self.eta():.0f} s left (Esc to cancel)")

    # A driving sensor's scan left under way while the next step starts (``step``). A
    # still sensor's never is: its next frame reuses this frame's static cast, which
    # is kept only once the cast is collected.
    overlap = True

    def step(self):
        """Do the next (frame, sensor); False when nothing is left or a cancel was
        asked for before this step's scan began. A driving sensor's step may leave its
        scan under way (``_pending``: its cast running) and finish it in the next
        step, after that step's scan has started: the casts overlap the steps' own
        work. Steps end in the plan's order either way."""
        if self.cancelled:
            return False
        if self._next >= len(self.plan):
            self._end_pending()
            return not self.finished
        frame, job = self.plan[self._next]
        out = job.settings.output
        kept, told = None, []
        if self.writer is not None:
            kept = self.writer.existing(job.name, out, frame, self._records[job.name])
            if kept is None:
                told = self._stale_notice(job, frame)
        if kept is not None:
            self._end_pending()
            self._next += 1
            if hasattr(self.writer, "kept_labels"):
                self._add_labels(self.writer.kept_labels(job.name, out, frame))
            self._done(frame, job, Step(frame, job.name, self.index + 1, self.total, kept, 0.0,
                                        str(self.writer.path(job.name, out, frame)), True))
            self.resumed += 1
            return not self.finished
        t_step = time.perf_counter()
        try:
            if self._frame_set != frame or self.source.current_frame() != frame:
                self.source.set_frame(frame)
                self._frame_set = frame
            if self._cancelled():
                self.cancelled = True
            else:
                t = time.perf_counter()
                session = self.sessions[job.settings.backend]
                classes = [label_id(c) for c in out.object_classes] if out.ground_truth \
                    else None
                # a writer behind the scan works the boxes out there, while the next
                # frames scan
                later = self.on_result is None and getattr(self.writer, "works_out_later",
                                                           False)
                steps = session.scan_started(self.source, job.name, job.preset,
                                             job.settings.scan, frame, object_classes=classes,
                                             values=self._values[job.name],
                                             boxes_later=later)
        except BaseException:
            # a failure or Ctrl+C here loses nothing done: the step under way ends first
            self._end_pending()
            raise
        if self.cancelled:
            self._end_pending()
            return False
        self._next += 1
        started = _Started(frame, job, told, steps, t_step, t, time.perf_counter())
        self._end_pending()
        if self.overlap and self.on_result is None and self._next < len(self.plan) \
                and self.source.sensor_may_move(job.name):
            self._pending = started
            return True
        self._finish(started)
        return not self.finished

    def _end_pending(self):
        """End the step under way, if there is one."""
        started, self._pending = self._pending, None
        if started is not None:
            self._finish(started)

    def _finish(self, started):
        """The rest of a step whose scan ``started`` (a ``_Started``): its result, its
        files."""
        frame, job, told, steps, t_step, t, t_started = started
        out = job.settings.output
        t_resume = time.perf_counter()
        result, info = finished(steps)
        if job.settings.scan.frame_space == "world":
            far = float32_warning(result.points, out.format)
            if far is not None:
                result.warnings.append(far)  # the sidecar's warnings too (the same list)
        info["frame_rate_hz"] = self.source.fps
        info["timestamp_s"] = out.start_time_s + (frame - self.source.frame_start) / self.source.fps
        self._add_labels(info["labels"])
        t_scanned = time.perf_counter()
        path = None
        if self.writer is not None:
            path = str(self.writer.write(job.name, out, frame, result.points, info))
            self.paths.append(path)
            if self._budget is not None:
                self._budget.written(job.name, run_files.files_of(self.writer, job, frame))
        if self.on_result is not None:
            self.on_result(job, frame, result, info)
        self.scanned += 1
        t_end = time.perf_counter()
        # the step's own time: its start and its finish (not the other steps' between)
        wall = (t_started - t_step) + (t_end - t_resume)
        self._scan_time += wall
        warnings = told + [f"{job.name} frame {frame}: {w}" for w in result.warnings]
        self.warnings += warnings
        self.last = (result, info)
        own = (t_started - t) + (t_scanned - t_resume)  # the session's, scan_frame's among it
        parts = dict(zip(STEP_PARTS, (t - t_step, max(0.0, own - result.seconds),
                                      result.seconds, t_end - t_scanned)))
        self._done(frame, job, Step(frame, job.name, self.index + 1, self.total,
                                    len(result.points), result.seconds, path, False,
                                    warnings=warnings, wall_s=wall, parts=parts))

    def _add_labels(self, labels):
        for iid, o in labels.items():
            self.id_map.setdefault(int(iid), {})[o["object"]] = o["label"]

    def _stale_notice(self, job, frame):
        """Once per sensor, when resuming: its earlier files written with other settings
        are scanned again, naming the settings that differ."""
        if not getattr(self.writer, "resume", False) or job.name in self._told_stale \
                or not hasattr(self.writer, "stale_settings"):
            return []
        names = self.writer.stale_settings(job.name, job.settings.output, frame,
                                           self._records[job.name])
        if not names:
            return []
        self._told_stale.add(job.name)
        return [f"{job.name}: frames written with other settings ({', '.join(names)}) "
                "are scanned again"]

    def _done(self, frame, job, step):
        self.index += 1
        self.points += step.points
        step.eta_s = self.eta()
        self.outputs.append(step)
        if self.index == len(self.plan) or self.plan[self.index][0] != frame:
            self.frames_done.append(frame)
        if self.index == len(self.plan):
            self._complete()
        if self.progress is not None:
            self.progress(step)

    def instance_table(self):
        """The run's objects by stable instance id (what every sidecar's ``labels``
        lists for its own scan), for the writer to store once per run."""
        return {str(i): {"object": name, "label": label, "label_name": label_name(label)}
                for i, names in sorted(self.id_map.items()) for name, label in names.items()}

    def _complete(self):
        if self.piece:
            return
        self.warnings += check_ids({i: set(n) for i, n in self.id_map.items()})
        if self.writer is not None:
            self.writer.finish(self)

    # ---- a run spread over workers ------------------------------------------------------

    def pieces(self, count, by_sensor=True):
        """The plan split into at most ``count`` pieces of [(sensor names, frames)]:
        per sensor, runs of consecutive frames (a worker keeps a still sensor's cast
        and a sensor's prepared scene over its frames); with ``by_sensor=False`` runs
        of frames with every sensor (layouts whose files need a whole frame)."""
        from .dask_run import shards

        if not by_sensor:
            return [([j.name for j in self.sensors], f) for f in shards(self.frames, count)]
        per = max(1, -(-count // len(self.sensors)))
        return [([j.name], f) for j in self.sensors for f in shards(self.frames, per)]

    def absorb(self, steps, id_map, warnings=()):
        """Take a piece's steps (run elsewhere) into this run, then, once every step of
        the plan is in, order them as a whole run would and complete the run."""
        jobs = {j.name: j for j in self.sensors}
        for step in steps:
            self.outputs.append(step)
            self.points += step.points
            if step.resumed:
                self.resumed += 1
            else:
                self.scanned += 1
                self._scan_time += step.wall_s or step.seconds
                if step.path:
                    self.paths.append(step.path)
                    if self._budget is not None:
                        self._budget.written(step.sensor, run_files.files_of(
                            self.writer, jobs[step.sensor], step.frame))
        for iid, names in id_map.items():
            self.id_map.setdefault(int(iid), {}).update(names)
        self.warnings += [w for w in warnings if w not in self.warnings]
        self.index = len(self.outputs)
        if self.index == len(self.plan):
            order = {(f, j.name): k for k, (f, j) in enumerate(self.plan)}
            self.outputs.sort(key=lambda s: order[(s.frame, s.sensor)])
            self.paths = [s.path for s in self.outputs if s.path and not s.resumed]
            for k, s in enumerate(self.outputs):
                s.done = k + 1
            self.frames_done = list(self.frames)
            self._complete()

    def remove_leftovers(self):
        """Remove what a killed process left of this run's outputs (``run_files``);
        only for runs that may replace their outputs (--resume, --overwrite) and once
        every worker stopped."""
        run_files.remove_leftovers(self.plan, self.writer)

    def still_sensors(self):
        """The sensors whose frames reuse their first frame's cast: those that cannot
        move, in a scene where nothing changes (the source's ``timeless``; a source that
        cannot tell: none). What the cost model of a run on workers counts."""
        timeless = getattr(self.source, "timeless", None)
        if timeless is None or not timeless():
            return set()
        return {j.name for j in self.sensors if not self.source.sensor_may_move(j.name)}

    def complete_on_disk(self):
        """How many scans of the plan have all their files, complete, now: what a run
        spread over workers has written when it stops between the pieces it has heard
        back from (``index`` counts those only)."""
        if self.writer is None:
            return self.index
        return run_files.complete_on_disk(self.plan, self.writer)

    def free_outputs(self):
        """Without --overwrite or --resume, an existing file of this run is an error
        before anything is scanned (``run_files.free_outputs``)."""
        run_files.free_outputs(self.plan, self.writer)

    def run(self, interrupt_cancels=False):
        """Every step to the end; Ctrl+C ends the run as a cancel when
        ``interrupt_cancels`` (scripts in Blender), else it propagates (the command
        line reports it). The source is put back at its frame either way.

        What exists when the run starts (Blender's own objects, the scene read) is kept
        out of Python's cyclic garbage collection while it runs (``gc.freeze``): a full
        collection walked all of it every thousand frames or so, a 20-30 ms stall in
        frames of 3 ms (bench/long_runs.py)."""
        gc.collect()
        gc.freeze()
        try:
            while self.step():
                pass
        except KeyboardInterrupt:
            if not interrupt_cancels:
                raise
            self.cancelled = True
        finally:
            gc.unfreeze()
            self.finish()
        return self

    def finish(self):
        """Put the scene back at the frame it was at when the run began; a run that
        ends before its last step (cancelled, interrupted, failed) drops what only a
        complete run may leave (a bag)."""
        if self._pending is not None:  # failed or interrupted with a scan under way
            self._pending.steps.close()  # its cast waited for, its step dropped
            self._pending = None
        if self.index < len(self.plan) and self.writer is not None and not self.piece:
            self.writer.abort()
        if self.writer is not None:  # a piece's files, complete
            self.writer.flush()
        if self.source.current_frame() != self.original_frame:
            self.source.set_frame(self.original_frame)

    def summary(self):
        """The run as plain data (the command line prints it as JSON)."""
        return {"scene": self.source.name, "frames": self.frames,
                "sensors": [j.name for j in self.sensors],
                "structure_builds": self.structure_builds, "points": self.points,
                "seconds": round(time.perf_counter() - self.t0, 3),
                "scanned": self.scanned, "resumed": self.resumed,
                "cancelled": self.cancelled,
                "outputs": [self._output(s) for s in self.outputs]}

    @staticmethod
    def _output(s):
        out = {"sensor": s.sensor, "frame": s.frame, "points": s.points,
               "seconds": round(s.seconds, 4), "wall_seconds": round(s.wall_s, 4),
               "file": s.path}
        if s.resumed:
            out["resumed"] = True
        return out

