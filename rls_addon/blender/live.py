"""Live coverage in Blender: the thin side of ``core.live``. While it is on, a change
handler notes which LiDARs changed (moved, turned, retargeted by a constraint, another
preset or setting, another frame) by comparing each LiDAR's pose, settings and frame
with the last seen: never any work there. A ``bpy.app.timers`` callback (``tick``)
lets the core's ``LiveScheduler`` decide: scan one still LiDAR (``scan``: the scene
read and the LiDAR scanned, as *Scan Frame* does), or show what was scanned
(``publish``: the previews, the region's numbers in ``Scene.rls_live``, the coverage
map over the InfraLOB). RLS's own updates feed back into the handler: they are
ignored while they are made (``busy``), and they change no LiDAR's signature anyway.

In the ``bpy`` module (no event loop) handlers run on ``view_layer.update()`` and
``frame_set``, and timers never fire: tests and the bench call ``tick()`` as the timer
would, when it asks to be called."""

import time

import bpy
from bpy.app.handlers import persistent

from ..core.casting import caster_factory
from ..core.errors import RLSError
from ..core.live.coverage import Coverage
from ..core.live.schedule import LIVE, LiveScheduler, LiveSettings
from ..core.scan.session import ScanSession
from .coverage_map import remove_coverage, show_coverage
from .preview import show_points
from .region import lob_polygon_world
from .sensor import lidar_objects, lidar_props, read_settings, sensor_job
from .source import BlenderScene
from .values import typed_float

_STATE = {"live": None}


def session():
    """The running ``LiveSession``, or None."""
    return _STATE["live"]


def is_live(scene):
    s = _STATE["live"]
    return s is not None and s.scene_name == scene.name


class LiveSession:
    """Live coverage of one scene over its InfraLOB ``lob_name``."""

    def __init__(self, scene, lob_name, settings, clock=time.perf_counter):
        self.scene_name, self.lob_name = scene.name, lob_name
        self.scheduler = LiveScheduler(self, clock, settings)
        self.sessions = {}       # backend -> ScanSession (prepared scenes kept)
        # (prepared around each pose as Scan Frame prepares it: its points are a fresh
        # scan's, to the bit; a grid of anchors, as for a driving LiDAR, saved about
        # 10 ms a move on the sample intersection but moved a few grazing hits)
        self.source = BlenderScene(scene)
        self.signatures = {}     # LiDAR name -> what a rescan depends on, last seen
        self.scanned = {}        # LiDAR name -> its signature when it was last scanned
        self.shown = {}          # LiDAR name -> its signature in the scan shown
        self.clouds = {}         # LiDAR name -> its latest world-frame points
        self.region = None       # the region's signature
        self.coverage = None
        self.busy = False
        self.error = ""

    @property
    def scene(self):
        return bpy.data.scenes.get(self.scene_name)

    # -- what changed (the handlers) ----------------------------------------------------

    def check(self):
        """Note the LiDARs whose pose, settings or frame changed, the ones gone, and a
        changed region (its numbers are counted again from the clouds kept)."""
        scene = self.scene
        if scene is None:
            return
        seen = {}
        for obj in lidar_objects(scene):
            settings = read_settings(obj)
            seen[obj.name] = (tuple(v for row in obj.matrix_world for v in row),
                              settings.preset, repr(settings.scan), settings.backend,
                              scene.frame_current)
        moved = [k for k, sig in seen.items() if self.signatures.get(k) != sig]
        back = [k for k in moved if self.shown.get(k) == seen[k]]
        changed = [k for k in moved if k not in back]
        gone = [k for k in self.signatures if k not in seen]
        self.signatures = seen
        self.scheduler.unchanged(back)
        for key in gone:
            self.scheduler.forget(key)
            self.clouds.pop(key, None)
            self.shown.pop(key, None)
            if self.coverage is not None:
                self.coverage.remove(key)
        self.scheduler.changed(changed)
        region = self._region_signature(scene)
        if region != self.region or gone:
            self.region = region
            self._new_coverage(scene)
            if not self.scheduler.busy:
                self.publish({})

    def _region_signature(self, scene):
        lob = scene.objects.get(self.lob_name)
        rs = scene.rls
        if lob is None:
            return None
        return (lob_polygon_world(lob).tobytes(), rs.metric_labels, rs.metric_disks,
                typed_float(rs.metric_radius), rs.metric_seed, typed_float(rs.metric_cell))

    def _new_coverage(self, scene):
        rs = scene.rls
        lob = scene.objects.get(self.lob_name)
        if lob is None:
            self.coverage = None
            self.error = f"the InfraLOB {self.lob_name!r} is gone: live coverage has no region"
            return
        self.coverage = Coverage(lob_polygon_world(lob), rs.metric_labels, rs.metric_disks,
                                 typed_float(rs.metric_radius), rs.metric_seed,
                                 cell=typed_float(rs.metric_cell))
        for key, points in self.clouds.items():
            self.coverage.set_cloud(key, points)

    # -- the scheduler's scanner ----------------------------------------------------------

    def scan(self, key):
        """LiDAR ``key`` scanned at the current frame: its points in the world frame."""
        scene = self.scene
        obj = scene.objects[key]
        self.scanned[key] = self.signatures.get(key)
        settings = read_settings(obj).override(frame_space="world")
        job = sensor_job(obj, settings)
        backend = settings.backend
        if backend not in self.sessions:
            self.sessions[backend] = ScanSession(caster_factory(backend)[0])
        result, _ = self.sessions[backend].scan(self._source(scene), key, job.preset,
                                                settings.scan, scene.frame_current)
        return result.points

    def _source(self, scene):
        """The scene source, made again when undo (or a reload) replaced the scene it
        held (its meshes read again; the prepared scenes are kept by their content)."""
        try:
            if self.source.scene.name == scene.name:
                return self.source
        except ReferenceError:
            pass
        self.source = BlenderScene(scene)
        return self.source

    def publish(self, ready):
        """Show the LiDARs rescanned (``{name: points}``) and the region's numbers and
        map over every LiDAR's latest points."""
        scene = self.scene
        self.busy = True
        try:
            for key, points in ready.items():
                obj = scene.objects.get(key)
                if obj is None:
                    continue
                self.clouds[key] = points
                self.shown[key] = self.scanned.get(key)
                show_points(scene, obj, points, "world", None,
                            color_by=lidar_props(obj).preview_color)
                if self.coverage is not None:
                    self.coverage.set_cloud(key, points)
            self._show_numbers(scene)
        finally:
            self.busy = False

    def _show_numbers(self, scene):
        props = scene.rls_live
        lob = scene.objects.get(self.lob_name)
        if self.coverage is None or lob is None:
            props.status = self.error or "no region"
            return
        state = self.coverage.state()
        show_coverage(scene, lob, state.density)
        finite = state.density.values[state.density.values == state.density.values]
        props.infra_d, props.infra_nuc = state.infra_d, state.infra_nuc
        props.points = state.n_points
        props.scale = float(finite.max()) if finite.size else 0.0
        props.sensors = ", ".join(state.sensors)
        self.show_status(scene)

    def show_status(self, scene):
        """The scheduler's counts, the last update's cost and what it is doing."""
        props, sched = scene.rls_live, self.scheduler
        props.scans, props.superseded = sched.scans, sched.superseded
        if sched.updates:
            last = sched.updates[-1]
            props.latency_ms = 1000 * last.latency_s
            props.work_ms = 1000 * last.work_s
        props.status = (sched.reason if sched.mode != LIVE else self.error
                        or f"live: {len(self.clouds)} LiDAR(s) over {self.lob_name}")

    # -- the timer ----------------------------------------------------------------------

    def tick(self):
        """One step of the scheduler; the seconds until the next call, or None."""
        self.busy = True
        try:
            wait = self.scheduler.tick()
            self.error = ""
        except RLSError as exc:  # a LiDAR with a bad setting: say so, keep watching
            self.error = f"error: {exc}"
            wait = None
        finally:
            self.busy = False
        scene = self.scene
        if scene is not None:
            self.show_status(scene)  # (the scheduler judges an update after showing it)
        return wait


# -- switching on and off, handlers and the timer -----------------------------------------

def start(scene, lob, debounce_ms, budget_ms, clock=time.perf_counter):
    """Live coverage of ``scene`` over ``lob``: every LiDAR scanned now (the first
    update prepares the scene), then rescanned as it changes."""
    stop()
    settings = LiveSettings(debounce_s=debounce_ms / 1000.0, budget_s=budget_ms / 1000.0)
    live = LiveSession(scene, lob.name, settings, clock)
    _STATE["live"] = live
    try:
        live.check()
        live.busy = True
        try:
            live.scheduler.update_now()
        finally:
            live.busy = False
    except BaseException:
        stop()
        raise
    for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post):
        if on_change not in handlers:
            handlers.append(on_change)
    if on_load not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(on_load)
    return live


def stop():
    """Live coverage off: handlers and timer removed, the map removed (the previews
    stay: they are the LiDARs' last scans)."""
    live = _STATE["live"]
    _STATE["live"] = None
    for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post,
                     bpy.app.handlers.load_pre):
        for fn in (on_change, on_load):
            while fn in handlers:
                handlers.remove(fn)
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    if live is not None:
        remove_coverage(live.lob_name)


def update_now():
    """Rescan every changed LiDAR and show them now (on demand)."""
    live = _STATE["live"]
    if live is None:
        return None
    live.check()
    live.busy = True
    try:
        got = live.scheduler.update_now()
    finally:
        live.busy = False
    live.scheduler.resume()
    live.show_status(live.scene)
    return got


@persistent
def on_change(scene, depsgraph=None):
    """depsgraph_update_post / frame_change_post: note changes, start the timer."""
    live = _STATE["live"]
    if live is None or live.busy or scene.name != live.scene_name:
        return
    live.check()
    if live.scheduler.busy and live.scheduler.mode == LIVE and not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=live.scheduler.settings.debounce_s)


@persistent
def on_load(*args):
    """Another file: live coverage ends (its handlers stay, idle, until the next start:
    a handler list is not changed while Blender runs it)."""
    _STATE["live"] = None
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)


def tick():
    """The timer's callback (``bpy.app.timers``): returns when to be called again."""
    live = _STATE["live"]
    if live is None or live.scene is None:
        return None
    return live.tick()
