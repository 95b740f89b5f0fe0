"""Motion over one LiDAR sweep, read from Blender's animation at sub-frame times.

Objects that cannot change (no animation data, drivers, constraints, shape-key
animation, physics or geometry nodes on them or their parents) are never sampled.
The others are sampled at a few times across the sweep with
``scene.frame_set(frame, subframe=...)``; samples are doubled until interpolating
between them reproduces the evaluated animation, then each object is classified:
static (nothing changed: costs nothing more), rigid (only its matrix changed: cast
exactly in its own frame) or deforming (its evaluated mesh changed: sub-steps).
"""

import math

import numpy as np

from .extract import GEOMETRY_TYPES, instance_key, read_positions

INTERP_TOLERANCE_M = 1e-4  # max error of pose interpolation between samples
MAX_SAMPLES = 65
MAX_SUBSTEPS = 64


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


def may_deform(obj):
    keys = getattr(getattr(obj, "data", None), "shape_keys", None)
    return bool(len(obj.modifiers) or (keys is not None and len(keys.key_blocks) > 1)
                or (obj.parent is not None and obj.parent_type in {"ARMATURE", "VERTEX",
                                                                     "VERTEX_3"}))


class SweepClock:
    """Maps seconds since the sweep start to Blender frames and sets the scene there."""

    def __init__(self, scene, frame, period):
        self.scene, self.frame, self.period = scene, int(frame), float(period)
        self.fps = scene.render.fps / scene.render.fps_base

    def set(self, t):
        x = self.frame + float(t) * self.fps
        whole = math.floor(x)
        self.scene.frame_set(whole, subframe=x - whole)

    def restore(self):
        self.scene.frame_set(self.frame)


def _read_state(depsgraph, keys, deform_keys, sensor_name):
    """World matrices of instances named in ``keys``, local vertices of those in
    ``deform_keys``, and the sensor matrix, at the depsgraph's current time."""
    mats, verts, sensor = {}, {}, None
    for inst in depsgraph.object_instances:
        orig = inst.object.original
        if orig.name == sensor_name and not inst.is_instance:
            sensor = np.array(inst.matrix_world, dtype=np.float64)
            continue
        key = instance_key(inst)
        if key in keys:
            mats[key] = np.array(inst.matrix_world, dtype=np.float64)
            if key in deform_keys and inst.object.type in GEOMETRY_TYPES:
                verts[key] = read_positions(inst.object)
    return mats, verts, sensor


def _interp_error(times, mats, probe_t, probe_m, points):
    """Largest distance between interpolated and evaluated positions of ``points``."""
    from ..core.motion import Track

    tr = Track(times, mats)
    got = tr.at(probe_t)
    p = np.c_[points, np.ones(len(points))]
    a = np.einsum("kij,nj->kni", got[:, :3, :], p)
    b = np.einsum("kij,nj->kni", probe_m[:, :3, :], p)
    return float(np.linalg.norm(a - b, axis=2).max())


def sample_sweep(context, clock, instances, candidates, sensor_obj, track_sensor):
    """Sample candidate instances (indices into ``instances``) and the sensor over the
    sweep. Returns (times, {index: (K,4,4)}, {index: [local vertices per sample]},
    sensor (K,4,4) or None)."""
    keys = {instances[k].key: k for k in candidates}
    deform_keys = set()
    for k in candidates:
        ob = context.scene.objects.get(instances[k].source)
        if ob is not None and may_deform(ob):
            deform_keys.add(instances[k].key)

    def state_at(t):
        clock.set(t)
        dg = context.evaluated_depsgraph_get()
        return _read_state(dg, keys, deform_keys, sensor_obj.name)

    n = 5
    times = np.linspace(0.0, clock.period, n)
    states = [state_at(t) for t in times]
    while n < MAX_SAMPLES:
        mids = (times[:-1] + times[1:]) / 2
        mid_states = [state_at(t) for t in mids]
        worst = 0.0
        for key, k in keys.items():
            inst = instances[k]
            corners = np.array([inst.vertices.min(0), inst.vertices.max(0)])
            mats = np.array([s[0].get(key, inst.matrix) for s in states])
            probe = np.array([s[0].get(key, inst.matrix) for s in mid_states])
            worst = max(worst, _interp_error(times, mats, mids, probe, corners))
        if track_sensor:
            mats = np.array([s[2] for s in states])
            probe = np.array([s[2] for s in mid_states])
            worst = max(worst, _interp_error(times, mats, mids, probe, np.zeros((1, 3))))
        merged_t = np.empty(2 * n - 1)
        merged_t[0::2], merged_t[1::2] = times, mids
        merged = [None] * (2 * n - 1)
        merged[0::2], merged[1::2] = states, mid_states
        times, states, n = merged_t, merged, 2 * n - 1
        if worst <= INTERP_TOLERANCE_M:
            break
    matrices = {k: np.array([s[0].get(instances[k].key, instances[k].matrix) for s in states])
                for k in candidates}
    vertices = {k: [s[1].get(instances[k].key) for s in states] for k in candidates
                if instances[k].key in deform_keys}
    sensor = np.array([s[2] for s in states]) if track_sensor else None
    return times, matrices, vertices, sensor


def deformation(vertex_samples):
    """Largest displacement of any vertex between consecutive samples' start and any
    other sample (0 when the mesh never changes; inf when its topology changes)."""
    first = vertex_samples[0]
    worst = 0.0
    for v in vertex_samples[1:]:
        if v is None or first is None or v.shape != first.shape:
            return math.inf
        worst = max(worst, float(np.abs(v - first).max()) if len(v) else 0.0)
    return worst


def substep_count(max_motion_m, tolerance_m, fixed=0):
    """Sub-steps for a deforming object: fixed, or enough that no vertex moves more than
    the tolerance within one sub-step (at most MAX_SUBSTEPS)."""
    if fixed:
        return int(fixed)
    if not math.isfinite(max_motion_m):
        return MAX_SUBSTEPS
    return int(min(MAX_SUBSTEPS, max(1, math.ceil(max_motion_m / max(tolerance_m, 1e-6)))))
