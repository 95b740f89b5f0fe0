"""A Blender scene as the core's scene source (``core.source.SceneSource``): the
depsgraph read at the current frame, motion read at sub-frame times."""

from dataclasses import replace

import numpy as np

from ..core.scene.source import Mobility, SceneRead
from .extract import MeshReader, instance_key, read_instances, read_mesh
from .motion import (SceneTime, SweepClock, history_free, instancer_may_move, may_deform,
                     may_move, mesh_is_fixed, read_state, still_objects, timeless)
from .read_rules import read_warnings
from .still_reads import StillReads


def traffic_span(scene):
    """(first, last) frame over which the scene's road users (objects labelled
    vehicle, pedestrian or cyclist) are keyed: the keys of the F-curves that change
    (two keys or more, not all of one value) in their own and their parents' actions;
    None when no road user is keyed so (``core.scene.traffic_keys``)."""
    import math

    from ..core.labels import OBJECT_CLASSES, label_id
    from .labels import object_label
    from .scenes.build import action_curves

    road_users = {label_id(n) for n in OBJECT_CLASSES}
    lo, hi, seen = math.inf, -math.inf, set()
    for obj in scene.objects:
        if object_label(obj) not in road_users:
            continue
        o = obj
        while o is not None:
            ad = o.animation_data
            action = ad.action if ad is not None else None
            if action is not None and action.name not in seen:
                seen.add(action.name)
                for fc in action_curves(action):
                    n = len(fc.keyframe_points)
                    if n < 2:
                        continue
                    co = np.empty(2 * n, np.float64)
                    fc.keyframe_points.foreach_get("co", co)
                    if np.ptp(co[1::2]) > 0:
                        lo, hi = min(lo, co[0::2].min()), max(hi, co[0::2].max())
            o = o.parent
    if lo > hi:
        return None
    return int(math.floor(lo + 1e-6)), int(math.ceil(hi - 1e-6))


class BlenderScene:
    """``scene`` (a ``bpy.types.Scene``) in ``context`` (default ``bpy.context``). One
    source serves a whole run: its ``MeshReader`` reads a mesh that does not change
    between frames once.

    ``edited=False`` promises that nobody edits the file while the source is used (the
    command line's background Blender, a worker): then, while nothing but the sensors
    can change over time (``motion.timeless``), a read is kept and given back for the
    next read from the same anchor and range, and the scene is not read again each
    frame. In Blender's interface (the default) every read reads."""

    def __init__(self, scene, context=None, edited=True):
        import bpy

        self.scene = scene
        self.context = context or bpy.context
        self.name = scene.name
        self.fps = scene.render.fps / scene.render.fps_base
        self.frame_start = scene.frame_start
        # an unedited file's meshes that cannot change are read once (mesh_is_fixed)
        self.meshes = MeshReader(fixed=None if edited else mesh_is_fixed)
        self.edited = edited
        self._kept_read = None  # (key, SceneRead) of the last read, when it may be kept
        self._timeless = {}     # exclude -> motion.timeless, for an unedited file
        self._mobility = {}     # what was read -> its Mobility, for an unedited file
        self._time = None       # SceneTime, for an unedited file without history (time())
        self._labels = None if edited else {}  # objects' labels, for an unedited file
        self._still = None  # StillReads of an unedited file (False: it has no still object)

    def depsgraph(self):
        self._settle()
        return self.context.evaluated_depsgraph_get()

    def current_frame(self):
        self._settle()
        return self.scene.frame_current

    def set_frame(self, frame):
        at = self.time()
        if at is not None:  # not set again when the last sweep's end is this frame
            at.set(frame)
        else:
            self.scene.frame_set(int(frame))

    def _settle(self):
        """Put the scene back where the last sweep left it owing (``SceneTime``)."""
        if self._time:
            self._time.settle()

    def time(self):
        """Where this source last set the scene (``motion.SceneTime``), kept for a file
        nobody edits whose scenes evaluate alike however a time is reached
        (``motion.history_free``); None otherwise: then every time is set."""
        if self.edited:
            return None
        if self._time is None:
            import bpy

            self._time = SceneTime(self.scene) if history_free(bpy.data) else False
        return self._time or None

    def sensor_pose(self, sensor):
        from ..core.errors import SceneError
        from .sensor import is_lidar

        obj = self.scene.objects.get(sensor)
        if obj is None or not is_lidar(obj):
            raise SceneError(f"LiDAR '{sensor}' is not in scene '{self.name}' (removed or "
                             "renamed while scanning?)")
        return np.array(obj.evaluated_get(self.depsgraph()).matrix_world, dtype=np.float64)

    def sensor_may_move(self, sensor):
        obj = self.scene.objects.get(sensor)
        return obj is not None and may_move(obj)

    def read(self, centre, max_range, exclude):
        key = (np.asarray(centre, np.float64).tobytes(), float(max_range), frozenset(exclude))
        if self._kept_read is not None and self._kept_read[0] == key:
            return self._kept_read[1]
        keeps = self._keeps_reads(key[2])
        still = None if keeps else self._still_reads()
        instances, materials, stats = read_instances(
            self.depsgraph(), centre=centre, max_range=max_range, exclude=set(exclude),
            reader=self.meshes, labels=self._labels,
            still=None if still is None else (still.names, still.at(key)))
        got = SceneRead(instances, materials, stats, read_warnings(stats))
        self._kept_read = (key, got) if keeps else None
        return got

    def _still_reads(self):
        """The ``StillReads`` of an unedited file with objects that cannot change over
        time (``still_reads``: what a read made of them is kept for the next read from
        the same place); None in Blender's interface, or when it has none."""
        if self.edited:
            return None
        if self._still is None:
            import bpy

            names = still_objects(bpy.data)
            self._still = StillReads(names) if names else False
        return self._still or None

    def timeless(self):
        """Whether nothing in the scene changes from frame to frame (no animation,
        driver, simulation or time-dependent modifier anywhere; never while the user
        may edit it)."""
        return self._keeps_reads(frozenset())

    def _keeps_reads(self, exclude):
        """Whether a read without the objects ``exclude`` may serve every frame."""
        if self.edited:
            return False
        if exclude not in self._timeless:
            import bpy

            self._timeless[exclude] = timeless(bpy.data, exclude)
        return self._timeless[exclude]

    def mobility(self, instances, sensor):
        # What may move cannot change while nobody edits the file: an unedited file's
        # answer is kept for the same objects read (a copy given back each time).
        key = None if self.edited else (sensor, tuple((i.key, i.source, i.parent)
                                                      for i in instances))
        kept = self._mobility.get(key) if key is not None else None
        if kept is None:
            kept = self._mobility_of(instances, sensor)
            if key is not None:
                if len(self._mobility) >= 16:
                    self._mobility.clear()
                self._mobility[key] = kept
        return Mobility(list(kept.candidates), set(kept.deformable), kept.sensor_moves)

    def _mobility_of(self, instances, sensor):
        import bpy

        # An instance's object and instancer are looked up in the file, not the scene:
        # a collection an instancer shows need not be linked to the scene at all.
        objects = bpy.data.objects
        out = Mobility(sensor_moves=may_move(self.scene.objects[sensor]))
        instancers = {}  # instancer name -> whether it or what it instances may move
        for k, inst in enumerate(instances):
            ob = objects.get(inst.source)
            par = objects.get(inst.parent) if inst.parent else None
            if par is not None and par.name not in instancers:
                instancers[par.name] = instancer_may_move(par)
            if (ob is not None and may_move(ob)) or (par is not None and instancers[par.name]):
                out.candidates.append(k)
                if ob is not None and may_deform(ob):
                    out.deformable.add(inst.key)
        return out

    def sweep(self, frame, period):
        return BlenderSweep(self, frame, period)

    def traffic_span(self):
        return traffic_span(self.scene)


class BlenderSweep:
    """The scene at sub-frame times over one sweep (``core.source.Sweep``)."""

    def __init__(self, source, frame, period):
        self.source = source
        self.clock = SweepClock(source.scene, frame, period, at=source.time())

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.clock.restore()

    def state(self, t, keys, deform_keys, sensor):
        at = self.clock.at
        if at is None:
            self.clock.set(t)
            return read_state(self.source.depsgraph(), keys, deform_keys, sensor)
        # an unedited, history-free file: a state at a whole frame is kept for the
        # next sweep (this sweep's end is the next frame's start)
        when = self.clock.when(t)
        got = at.kept(when, keys, deform_keys, sensor)
        if got is None:
            self.clock.set(t)
            got = read_state(self.source.depsgraph(), keys, deform_keys, sensor)
            at.keep(when, keys, deform_keys, sensor, got)
        return got

    def instance_at(self, t, instance):
        self.clock.set(t)
        for i in self.source.depsgraph().object_instances:
            if instance_key(i) == instance.key:
                co, tri, mat = read_mesh(i.object)
                return replace(instance, vertices=co, triangles=tri,
                               materials=instance.material_indices(mat),
                               matrix=np.array(i.matrix_world, dtype=np.float64))
        return None
