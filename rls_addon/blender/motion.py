"""Motion in Blender: what may change over time, and the scene at sub-frame times.

Objects that cannot change (no animation data, drivers, constraints, shape-key
animation, physics or geometry nodes on them or their parents) are never sampled; the
others are read at times across the sweep with ``scene.frame_set(frame,
subframe=...)``. How many samples, and what moves how, is the core's decision
(``core.sweep``).

In a file nobody edits whose scenes evaluate the same at a time however it is reached
(``history_free``: no simulation, rigid body, particles or geometry nodes), a
``SceneTime`` saves what would be read twice: the scene is not set again where it
already is (a sweep's start, at the frame the run has just set), and a state read at a
whole frame (a sweep's end) is given back at the next sweep's start.
"""

import math

import numpy as np

from .extract import instance_key, read_positions
from .read_rules import GEOMETRY_TYPES, is_rls_helper


def _animated(idblock):
    ad = getattr(idblock, "animation_data", None)
    return bool(ad and (ad.action or len(ad.drivers) or len(ad.nla_tracks)))


def may_move(obj):
    """True when anything could move or deform ``obj`` over time."""
    o = obj
    while o is not None:
        if _animated(o) or len(o.constraints) or getattr(o, "rigid_body", None):
            return True
        if _animated(getattr(o, "data", None)):
            return True
        keys = getattr(getattr(o, "data", None), "shape_keys", None)
        if keys is not None and _animated(keys):
            return True
        if any(m.type in {"NODES", "ARMATURE", "CLOTH", "SOFT_BODY", "OCEAN", "WAVE",
                          "DYNAMIC_PAINT", "FLUID", "EXPLODE"} for m in o.modifiers):
            return True
        o = o.parent
    return False


def instancer_may_move(obj):
    """True when anything could move what the instancer ``obj`` places: ``obj`` itself
    (``may_move``) or, for a collection instance, any object of its collection, or of
    the collections instanced in turn inside it. A depsgraph instance names only its
    top instancer and its object, so an animated empty between them (a nested
    collection instance) is found here, or the instance would be read as still."""
    seen, stack = set(), [obj]
    while stack:
        o = stack.pop()
        if o.name_full in seen:
            continue
        seen.add(o.name_full)
        if may_move(o):
            return True
        coll = o.instance_collection if o.instance_type == "COLLECTION" else None
        if coll is not None:
            stack.extend(coll.all_objects)
    return False


# Modifiers whose result may change from frame to frame with no keyframe or driver:
# simulations, caches, and those taking the frame or the scene time as an input.
_CHANGE_BY_THEMSELVES = {"NODES", "ARMATURE", "CLOTH", "SOFT_BODY", "OCEAN", "WAVE",
                         "DYNAMIC_PAINT", "FLUID", "EXPLODE", "PARTICLE_SYSTEM",
                         "PARTICLE_INSTANCE", "BUILD", "MESH_CACHE", "MESH_SEQUENCE_CACHE",
                         "COLLISION", "SURFACE"}


def timeless(data, exclude=()):
    """True when nothing in the file ``data`` (``bpy.data``) but the objects named in
    ``exclude`` can change from frame to frame: no other object moves or deforms
    (``may_move``, or a modifier that changes by itself) and no other data-block
    (mesh, material, node group, texture, world, scene ...) is animated or driven.
    Then every frame of the scene reads the same, but for those objects."""
    for obj in data.objects:
        if obj.name in exclude or is_rls_helper(obj):  # never read
            continue
        if may_move(obj) or any(m.type in _CHANGE_BY_THEMSELVES for m in obj.modifiers):
            return False
    return _blocks_still(data)


def _blocks_still(data):
    """True when no data-block of ``data`` but its objects (a mesh, material, node group,
    texture, world, scene ...) is animated or driven."""
    return not any(_animated(block) or _animated(getattr(block, "node_tree", None))
                   for block in _data_blocks(data, skip={"objects"}))


def _data_blocks(data, skip):
    """Every data-block of ``data`` (``bpy.data``) outside its collections ``skip``."""
    for prop in data.bl_rna.properties:
        if prop.type == "COLLECTION" and prop.identifier not in skip:
            yield from getattr(data, prop.identifier)


def mesh_is_fixed(obj):
    """True when ``obj``'s evaluated mesh cannot change over time or with other
    objects while nobody edits the file: a mesh object without modifiers or shape keys,
    whose mesh is neither animated nor driven, parented (if at all) to an object or a
    bone, which move it but do not deform it (an armature, lattice or vertex parent
    may). What a background Blender may read once (``extract.MeshReader``)."""
    data = getattr(obj, "data", None)
    return (obj.type == "MESH" and data is not None and not len(obj.modifiers)
            and getattr(data, "shape_keys", None) is None and not _animated(data)
            and (obj.parent is None or obj.parent_type in {"OBJECT", "BONE"}))


def object_is_still(obj):
    """True when nothing can change ``obj``'s read over time in a file nobody edits
    (given the file's other data-blocks still: ``still_objects``)."""
    return (obj.type == "MESH" and obj.parent is None and obj.instance_type == "NONE"
            and mesh_is_fixed(obj) and not may_move(obj))


def still_objects(data):
    """Names of the objects of ``data`` (``bpy.data``) that cannot change over time: none
    when a data-block other than an object (a mesh, material, node group, texture,
    world, scene...) is animated or driven, or the file has history
    (``motion.history_free``)."""
    if not (history_free(data) and _blocks_still(data)):
        return frozenset()
    return frozenset(o.name for o in data.objects if object_is_still(o))


def may_deform(obj):
    keys = getattr(getattr(obj, "data", None), "shape_keys", None)
    return bool(len(obj.modifiers) or (keys is not None and len(keys.key_blocks) > 1)
                or (obj.parent is not None and obj.parent_type in {"ARMATURE", "VERTEX",
                                                                     "VERTEX_3"}))


class SweepClock:
    """Maps seconds since the sweep start to Blender frames and sets the scene there.

    ``at``: a ``SceneTime`` that knows where its source last set the scene, or None.
    With one, a time the scene is already at is not set again (the sweep's start, at
    the frame the run has just set: one frame change of ten a frame saved); without
    one every time is set."""

    def __init__(self, scene, frame, period, at=None):
        self.scene, self.frame, self.period = scene, int(frame), float(period)
        self.fps = scene.render.fps / scene.render.fps_base
        self.at = at

    def when(self, t):
        """(frame, subframe) of ``t`` seconds since the sweep start."""
        x = self.frame + float(t) * self.fps
        whole = math.floor(x)
        return whole, x - whole

    def set(self, t):
        self._set(*self.when(t))

    def restore(self):
        """Back at the frame: at once, or (with a ``SceneTime``) owed until the scene
        is next read (``SceneTime.settle``); a run that goes on to the next frame, which
        the sweep's end has just set, never pays it."""
        if self.at is not None:
            self.at.owe(self.frame)
        else:
            self.scene.frame_set(self.frame)

    def _set(self, whole, subframe):
        if self.at is not None:
            self.at.set(whole, subframe)
        else:
            self.scene.frame_set(whole, subframe=subframe)


class SceneTime:
    """Where a source last set its scene (frame, subframe), for a file nobody edits and
    whose scene evaluates the same at a time however it got there (``history_free``):
    then setting the scene to where it is changes nothing, and is skipped. Checked
    against the scene's own frame and subframe too, so a frame set by anyone else is
    never taken for ours. A sweep's way back to its frame is owed (``owe``) until the
    source is next read (``settle``) or set to another frame, which drops it."""

    KEEP_STATES = 8  # states kept at whole frames (a sweep's end is the next one's start), per sensor

    def __init__(self, scene):
        self.scene, self.last = scene, None
        self.owed = None   # the frame a sweep left the scene to be put back at
        self._states = {}  # ((frame, 0.0), sensor) -> (keys, state read there)

    def set(self, frame, subframe=0.0):
        """Set the scene at (``frame``, ``subframe``) unless it is there already; what
        was owed is superseded."""
        self.owed = None
        if not self.is_at(frame, subframe):
            self._set(frame, subframe)

    def _set(self, frame, subframe=0.0):
        self.scene.frame_set(int(frame), subframe=float(subframe))
        self.last = (int(frame), float(subframe))

    def owe(self, frame):
        self.owed = int(frame)

    def settle(self):
        """Put the scene back at the frame a sweep left it owing (if any), as the
        sweep's end would have; not when anyone else has set the scene since (it is
        no longer where this source left it)."""
        if self.owed is not None:
            frame, self.owed = self.owed, None
            if self.last is not None and self.is_at(*self.last) and not self.is_at(frame, 0.0):
                self._set(frame)

    def kept(self, when, keys, deform_keys, sensor):
        """The state read at ``when`` (a whole frame) of these ``keys`` and ``sensor``,
        or None: what a sweep's end read, given back at the next frame's start (never
        a deforming object's vertices: those are always read)."""
        got = self._states.get((when, sensor)) if not deform_keys else None
        if got is None or not got[0].issuperset(keys):
            return None
        mats, _, sensor_m = got[1]
        return {k: mats[k] for k in keys if k in mats}, {}, sensor_m

    def keep(self, when, keys, deform_keys, sensor, state):
        """Keep ``state`` (read at ``when``) when ``when`` is a whole frame."""
        if deform_keys or when[1] != 0.0:
            return
        mats, _, sensor_m = state
        frozen = {k: _read_only(m) for k, m in mats.items()}
        self._states.pop((when, sensor), None)
        while len(self._states) >= self.KEEP_STATES:
            self._states.pop(next(iter(self._states)))
        self._states[(when, sensor)] = (frozenset(keys), (frozen, {}, _read_only(sensor_m)))

    def is_at(self, frame, subframe):
        return (self.last == (int(frame), float(subframe))
                and self.scene.frame_current == self.last[0]
                and self.scene.frame_subframe == self.last[1])


def _read_only(m):
    """A read-only copy of matrix ``m`` (None stays None)."""
    if m is None:
        return None
    m = m.copy()
    m.setflags(write=False)
    return m


# What makes a scene's state at a frame depend on the frames evaluated before it
# (caches filled as frames go by): simulations, particles and geometry nodes (whose
# simulation zones step from frame to frame).
_STEPPED = {"CLOTH", "SOFT_BODY", "FLUID", "DYNAMIC_PAINT", "PARTICLE_SYSTEM", "EXPLODE",
            "NODES", "COLLISION"}


def history_free(data):
    """True when no scene in ``data`` (``bpy.data``) has a rigid-body world and no
    object a rigid body or a modifier that steps from frame to frame (``_STEPPED``):
    then a scene evaluated at a time reads the same whichever times came before."""
    if any(getattr(sc, "rigidbody_world", None) is not None for sc in data.scenes):
        return False
    return not any(getattr(o, "rigid_body", None) is not None
                   or any(m.type in _STEPPED for m in o.modifiers) for o in data.objects)


def read_state(depsgraph, keys, deform_keys, sensor_name):
    """World matrices of instances named in ``keys``, local vertices of those in
    ``deform_keys``, and the sensor matrix, at the depsgraph's current time.

    Where no vertices are wanted and the depsgraph lists no instances beside its
    objects (``_object_matrices``), every object's matrix comes in one call; otherwise
    (and as the reference, ``_walk_state``) the instances are walked one by one."""
    if not keys:  # the sensor alone (a drive through a still scene): no walk over all
        obj = depsgraph.objects.get(sensor_name) if sensor_name else None
        return {}, {}, None if obj is None else np.array(obj.matrix_world, np.float64)
    if not deform_keys:
        got = _object_matrices(depsgraph)
        if got is not None:
            names, m = got
            mats, sensor = {}, None
            for j, name in enumerate(names):
                if name == sensor_name:
                    sensor = m[j]
                elif name in keys:
                    mats[name] = m[j]
            return mats, {}, sensor
    return _walk_state(depsgraph, keys, deform_keys, sensor_name)


def _object_matrices(depsgraph):
    """(names, (N, 4, 4) float64 world matrices) of the depsgraph's objects, the
    matrices in one ``foreach_get``; None when it lists instances beside its objects
    (a collection instance, particles, curves or text made meshes: ``object_instances``
    then has more entries than ``objects``, and those need ``_walk_state``). Without
    them the two list the same objects, each object's instance an object itself keyed
    by its name (``instance_key``), with the same float32 matrix (Blender's are
    column-major: transposed here); tested against ``_walk_state``."""
    objects = depsgraph.objects
    names = objects.keys()
    if len(depsgraph.object_instances) != len(names):
        return None
    flat = np.empty(16 * len(names), np.float32)
    objects.foreach_get("matrix_world", flat)
    return names, flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


def _walk_state(depsgraph, keys, deform_keys, sensor_name):
    """``read_state`` by a walk over every instance: the reference of its one call."""
    mats, verts, sensor = {}, {}, None
    for inst in depsgraph.object_instances:
        if inst.is_instance:
            key = instance_key(inst)
        else:  # an object itself: its key is its name (instance_key), or the sensor's
            key = inst.object.original.name
            if key == sensor_name:
                sensor = np.array(inst.matrix_world, dtype=np.float64)
                continue
        if key in keys:
            mats[key] = np.array(inst.matrix_world, dtype=np.float64)
            if key in deform_keys and inst.object.type in GEOMETRY_TYPES:
                verts[key] = read_positions(inst.object)
    return mats, verts, sensor
