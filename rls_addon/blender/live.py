"""Live coverage in Blender: the thin side of ``core.live``. While it is on, a change
handler notes which LiDARs changed (moved, turned, retargeted by a constraint, another
preset or setting, another frame) by comparing each LiDAR's pose, settings and frame
with the last seen: never any work there. A ``bpy.app.timers`` callback (``tick``)
lets the core's ``LiveScheduler`` decide: scan one still LiDAR (``scan``: the scene
read and the LiDAR scanned, as *Scan Frame* does), or show what was scanned
(``publish``: the previews, the region's numbers in ``Scene.rls_live``, the coverage
map over the InfraLOB). RLS's own updates feed back into the handler: they are
ignored while they are made (``busy``), and they change no LiDAR's signature anyway.

A still LiDAR's rescan reuses the frame's sampled sweep of the other objects (``sweeps``:
``core.scan.kept_sweeps``), so moving it does not sample the traffic's motion again.
The samples are forgotten whenever they may be stale: another object is moved,
re-animated or re-shaped (a depsgraph update of its transform or geometry:
``changes_others``), the frame rate or time mapping changes, undo or redo, a scene with
a rigid body world (its simulation is not kept), another file (live coverage ends).
The frame and the preset's sweep time are part of their key.

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
from ..core.scan.kept_sweeps import KeptSweeps
from ..core.scan.session import ScanSession
from .coverage_map import remove_coverage, show_coverage
from .read_rules import GEOMETRY_TYPES, is_rls_helper
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
        self.sweeps = KeptSweeps()  # the other objects' sampled sweeps (module docstring)
        self.timing = _timing(scene)
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
        if _timing(scene) != self.timing:  # sub-frame times fall elsewhere
            self.timing = _timing(scene)
            self.scene_edited()
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

    def scene_edited(self):
        """Something other than the LiDARs changed (another object, the frame rate, an
        undo): the kept sweeps are forgotten and every LiDAR is rescanned once the
        scene is still (none is 'back where it was shown' any more)."""
        self.sweeps.clear()
        self.shown = {}
        self.scheduler.changed(sorted(self.signatures))

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
        # (a simulation's states are not kept: its world's settings are the scene's)
        self.sessions[backend].kept_sweeps = None if _simulated(scene) else self.sweeps
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
        self.sweeps.clear()
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
        props.on_demand = sched.mode != LIVE
        redraw_panels()

    # -- the timer ----------------------------------------------------------------------

    def tick(self):
        """One step of the scheduler; the seconds until the next call, or None."""
        flush_edits()
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


def _timing(scene):
    """What maps a sweep's seconds to Blender's sub-frames (``motion.SweepClock``) and
    the scene's time."""
    r = scene.render
    return (r.fps, r.fps_base, r.frame_map_old, r.frame_map_new)


def _simulated(scene):
    world = scene.rigidbody_world
    return world is not None and world.enabled


def changes_others(updates):
    """Whether a depsgraph's ``updates`` say the scene a LiDAR sees changed, other than
    the LiDARs: an object with geometry (or one instancing a collection) that is not
    RLS's own (previews, the map, outlines, regions) updated in its transform or
    geometry (moved, re-animated, a constraint's target or a driver's input moved, its
    mesh or modifiers edited, added, parented), or the scene's (an object deleted or
    unlinked). Not: shading-only updates (Blender lists every object so when RLS
    replaces a preview's mesh; a material or a visibility change is one too: *Update
    Coverage* rescans then), the scene's bare update (its frame rate is compared apart:
    ``_timing``), empties, lights and cameras (what they drive is listed itself)."""
    for u in updates:
        idb = u.id
        if not (u.is_updated_transform or u.is_updated_geometry):
            continue
        if isinstance(idb, bpy.types.Scene):
            return True
        if isinstance(idb, bpy.types.Object):
            obj = idb.original
            if ((obj.type in GEOMETRY_TYPES or obj.instance_type != "NONE")
                    and not is_rls_helper(obj)):
                return True
    return False


def redraw_panels():
    """Redraw the Properties editors and 3D viewports of every window: a timer's writes
    to Python-defined properties send Blender no notifier, so the panel's numbers would
    wait for the mouse (no window in the bpy module: nothing to do)."""
    wm = getattr(bpy.context, "window_manager", None)
    for window in (wm.windows if wm is not None else ()):
        for area in window.screen.areas:
            if area.type in {"PROPERTIES", "VIEW_3D"}:
                area.tag_redraw()


def flush_edits():
    """Let Blender evaluate edits not evaluated yet (a script's), so that the change
    handler sees them before a scan reads the scene (inside a scan RLS ignores it)."""
    try:
        bpy.context.evaluated_depsgraph_get()
    except (AttributeError, RuntimeError):  # no view layer in this context
        pass


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
    for handlers, fn in _handlers():
        if fn not in handlers:
            handlers.append(fn)
    return live


def _handlers():
    """(handler list, function) of live coverage."""
    h = bpy.app.handlers
    return ((h.depsgraph_update_post, on_edit), (h.frame_change_post, on_change),
            (h.undo_post, on_undo), (h.redo_post, on_undo), (h.load_pre, on_load))


def stop():
    """Live coverage off: handlers and timer removed, the map removed (the previews
    stay: they are the LiDARs' last scans)."""
    live = _STATE["live"]
    _STATE["live"] = None
    for handlers, fn in _handlers():
        while fn in handlers:
            handlers.remove(fn)
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    if live is not None:
        remove_coverage(live.lob_name)


def update_now():
    """Rescan every changed LiDAR and show them now (on demand); with none changed,
    every LiDAR, the scene sampled anew (after an edit live coverage does not follow:
    a material, a visibility)."""
    live = _STATE["live"]
    if live is None:
        return None
    flush_edits()
    live.check()
    if not live.scheduler.busy:
        live.scene_edited()
    live.busy = True
    try:
        got = live.scheduler.update_now()
    finally:
        live.busy = False
    live.scheduler.resume()
    live.show_status(live.scene)
    return got


@persistent
def on_edit(scene, depsgraph=None):
    """depsgraph_update_post: as ``on_change``, and when another object changed the
    kept sweeps are forgotten and every LiDAR is rescanned (``scene_edited``)."""
    live = _STATE["live"]
    if live is None or live.busy or scene.name != live.scene_name:
        return
    live.check()
    if depsgraph is not None and changes_others(depsgraph.updates):
        live.scene_edited()
    _wake(live)


@persistent
def on_undo(scene, *args):
    """undo_post / redo_post: the scene was replaced: sample its sweeps anew and
    rescan every LiDAR."""
    live = _STATE["live"]
    if live is not None and not live.busy:
        live.scene_edited()
        _wake(live)


@persistent
def on_change(scene, depsgraph=None):
    """frame_change_post (and ``on_edit``): note changes, start the timer."""
    live = _STATE["live"]
    if live is None or live.busy or scene.name != live.scene_name:
        return
    live.check()
    _wake(live)


def _wake(live):
    """The timer started when there is something to rescan (and live, not on demand)."""
    if live.scheduler.busy and live.scheduler.mode == LIVE and not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=live.scheduler.settings.debounce_s)


@persistent
def on_load(*args):
    """Another file: live coverage ends, its handlers with it (but this one, idle until
    the next start: a handler list is not changed while Blender runs it)."""
    _STATE["live"] = None
    for handlers, fn in _handlers():
        if fn is not on_load:
            while fn in handlers:
                handlers.remove(fn)
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)


def tick():
    """The timer's callback (``bpy.app.timers``): returns when to be called again."""
    live = _STATE["live"]
    if live is None or live.scene is None:
        return None
    return live.tick()
