"""Motion over one sweep: sampling a scene source's animation and classifying what moves.

Objects that may change (``SceneSource.mobility``) and a sensor that may move are
sampled at a few times across the sweep (``Sweep.state``); samples are doubled until
interpolating between them reproduces the animation within ``INTERP_TOLERANCE_M``.
Each object is then static (nothing changed: costs nothing more), rigid (only its
matrix changed: cast exactly in its own frame) or deforming (its mesh changed:
sub-steps, each a mesh built at the middle of its part of the sweep).

How many sub-steps: a fixed N, or (N = 0) enough that nothing moves more than the
tolerance within one sub-step (``substep_count``). In "substeps" motion mode the whole
sweep uses one N, recorded in the sidecar; in "exact" mode only deforming objects are
sub-stepped, each with its own N.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ..scene.motion import Track, polar_parts
from ..scene.track_set import TrackSet

INTERP_TOLERANCE_M = 1e-4  # max error of pose interpolation between samples
MAX_SAMPLES = 65
MAX_SUBSTEPS = 64


def _interp_error(times, mats, probe_t, probe_m, points):
    """Largest distance between interpolated and evaluated positions of ``points``:
    one body's, the reference of ``_interp_errors``."""
    return _error(Track(times, mats).at(probe_t), probe_m, points)


def _error(got, probe_m, points):
    p = np.c_[points, np.ones(len(points))]
    a = np.einsum("kij,nj->kni", got[:, :3, :], p)
    b = np.einsum("kij,nj->kni", probe_m[:, :3, :], p)
    return float(np.linalg.norm(a - b, axis=2).max())


def _interp_errors(times, mats, probe_t, probe_m, points, parts=None):
    """``_interp_error`` of M bodies sampled at the same times ((M, K, 4, 4) ``mats``,
    (M, P, 4, 4) ``probe_m``, a list of M point arrays): their tracks made and
    evaluated together (``Track.many``, ``TrackSet``) and every body's distances in one
    product (``_errors``): the same numbers, body for body. ``parts``: ``mats``'
    ``polar_parts``, when made already (two bodies or more)."""
    if not len(mats):
        return []
    p = len(probe_t)
    if len(mats) == 1:  # a sensor driving through a still scene: one track, Track's own
        got = Track(times, mats[0]).at(probe_t)
    else:
        tracks = Track.many(times, mats, parts)
        got = TrackSet(tracks).at(np.repeat(np.arange(len(tracks)), p),
                                  np.tile(np.asarray(probe_t, np.float64), len(tracks)))
    return _errors(got.reshape(len(mats), p, 4, 4), probe_m, points)


def _errors(got, probe_m, points):
    """``_error`` of M bodies at once ((M, P, 4, 4) ``got`` and ``probe_m``, a list of M
    point arrays): each body's points padded to the most any has with its own last
    point (which changes no maximum), then one einsum of the same terms in the same
    order as ``_error``'s, so each body's largest distance is the same float."""
    n = max(len(q) for q in points)
    p = np.ones((len(points), n, 4))
    for j, q in enumerate(points):
        p[j, :len(q), :3] = q
        p[j, len(q):, :3] = q[-1]
    a = np.einsum("mkij,mnj->mkni", got[:, :, :3, :], p)
    b = np.einsum("mkij,mnj->mkni", probe_m[:, :, :3, :], p)
    return [float(e) for e in np.linalg.norm(a - b, axis=3).max(axis=(1, 2))]


def sample_sweep(sweep, period, instances, candidates, deform_keys, sensor, track_sensor):
    """Sample candidate instances (indices into ``instances``) and the sensor over a
    sweep of ``period`` seconds. Returns (times, {index: (K,4,4)}, {index: [local
    vertices per sample]}, sensor (K,4,4) or None, {index: the (K,4,4)'s
    ``polar_parts``} or None).

    With two bodies or more (the sensor counts), each sample's matrices are decomposed
    once, as they are read (``polar_parts``), for the error checks of every round and
    the tracks ``classify`` makes, instead of each time a track is made of them."""
    keys = {instances[k].key: k for k in candidates}
    deform_keys = {instances[k].key for k in candidates} & set(deform_keys)
    order = list(keys.items())
    corners = [np.array([instances[k].vertices.min(0), instances[k].vertices.max(0)])
               for _, k in order]
    if track_sensor:
        corners.append(np.zeros((1, 3)))

    defaults = [instances[k].matrix for _, k in order]

    def state_at(t):
        """(the state's (M, 4, 4) matrices of every sampled body, the sensor's last; the
        state's deforming vertices)."""
        mats, verts, sensor_m = sweep.state(t, keys, deform_keys, sensor)
        rows = [mats.get(key, d) for (key, _), d in zip(order, defaults)]
        if track_sensor:
            rows.append(sensor_m)
        return np.array(rows, np.float64).reshape(len(rows), 4, 4), verts

    def stacked(states):
        """(M, S, 4, 4): every sampled body's matrices (the sensor's last)."""
        return np.stack([s[0] for s in states], axis=1)

    n = 5
    times = np.linspace(0.0, period, n)
    # The sweep's end is read last, after the first midpoints: a source stepping
    # through its scene (Blender) is left at the next frame's start, where a run goes
    # next. Every state is read once whatever the order.
    states = [state_at(t) for t in times[:-1]]
    every = parts = None  # parts: every's polar_parts, with two bodies or more
    while n < MAX_SAMPLES:
        mids = (times[:-1] + times[1:]) / 2
        mid_states = [state_at(t) for t in mids]
        if every is None:
            states.append(state_at(times[-1]))
            every = stacked(states)
        at_mids = stacked(mid_states)
        if len(every) > 1:
            parts = polar_parts(every) if parts is None else parts
            mid_parts = polar_parts(at_mids)
        # every body at once: the same errors as one body at a time (_interp_error)
        worst = max(_interp_errors(times, every, mids, at_mids, corners, parts), default=0.0)
        merged_t = np.empty(2 * n - 1)
        merged_t[0::2], merged_t[1::2] = times, mids
        merged = [None] * (2 * n - 1)
        merged[0::2], merged[1::2] = states, mid_states
        both = _interleaved(every, at_mids)
        if parts is not None:
            parts = tuple(_interleaved(a, b) for a, b in zip(parts, mid_parts))
        times, states, every, n = merged_t, merged, both, 2 * n - 1
        if worst <= INTERP_TOLERANCE_M:
            break
    if every is None:  # (no midpoints at all)
        states.append(state_at(times[-1]))
        every = stacked(states)
    matrices = {k: every[j] for j, (_, k) in enumerate(order)}
    vertices = {k: [s[1].get(instances[k].key) for s in states] for k in candidates
                if instances[k].key in deform_keys}
    sensor_mats = every[-1] if track_sensor else None
    decomposed = None if parts is None else {
        k: (parts[0][j], parts[1][j]) for j, (_, k) in enumerate(order)}
    return times, matrices, vertices, sensor_mats, decomposed


def _interleaved(a, b):
    """(M, 2S - 1, ...): the S columns of ``a`` with the S - 1 of ``b`` between them
    (a sweep's samples with their midpoints)."""
    out = np.empty((a.shape[0], a.shape[1] + b.shape[1]) + a.shape[2:])
    out[:, 0::2], out[:, 1::2] = a, b
    return out


def deformation(vertex_samples):
    """Largest displacement of any vertex between the first sample and any other (0 when
    the mesh never changes; inf when its topology changes)."""
    first = vertex_samples[0]
    worst = 0.0
    for v in vertex_samples[1:]:
        if v is None or first is None or v.shape != first.shape:
            return math.inf
        worst = max(worst, float(np.abs(v - first).max()) if len(v) else 0.0)
    return worst


def substep_count(max_motion_m, tolerance_m, fixed=0):
    """Sub-steps: ``fixed``, or (0) enough that nothing moves more than the tolerance
    within one sub-step (at least 1, at most ``MAX_SUBSTEPS``)."""
    if fixed:
        return int(fixed)
    if not math.isfinite(max_motion_m):
        return MAX_SUBSTEPS
    return int(min(MAX_SUBSTEPS, max(1, math.ceil(max_motion_m / max(tolerance_m, 1e-6)))))


def adaptive_substeps(bodies, sensor_track, tolerance_m):
    """The sub-step count of "substeps" motion with N = 0, for bodies already built:
    enough that no rigid body's box corner nor the sensor moves more than
    ``tolerance_m`` within one sub-step (deforming bodies were sub-stepped when they
    were built)."""
    from ..world.bodies import RigidBodies

    worst = 0.0
    for b in bodies:
        if isinstance(b, RigidBodies):
            for k, track in enumerate(b.tracks):
                worst = max(worst, track.max_displacement(np.array(b.boxes[k])))
    if sensor_track is not None:
        worst = max(worst, sensor_track.max_displacement(np.zeros((1, 3))))
    return substep_count(worst, tolerance_m)


def box_corners(vertices):
    """The two extreme corners of local vertices (what ``Track.max_displacement``
    needs to bound a body's travel)."""
    return np.array([vertices.min(0), vertices.max(0)])


@dataclass
class SweepMotion:
    """What moves in one sweep, classified."""

    times: np.ndarray = None
    rigid: list = field(default_factory=list)      # [(instance index, Track)]
    deforming: list = field(default_factory=list)  # [(instance index, motion in m)]
    tracks: dict = field(default_factory=dict)     # {instance index: Track of its matrix}
    sensor: Track = None                           # a moving sensor's track, or None
    samples: int = 1

    @property
    def moved(self):
        """Instance indices that are not static in this sweep."""
        return {k for k, _ in self.rigid} | {k for k, _ in self.deforming}

    def max_travel(self, instances):
        """The farthest anything moves over the sweep (metres): rigid bodies' box
        corners, deforming meshes (their own change plus their travel) and the sensor.
        What an adaptive sub-step count is chosen from."""
        worst = 0.0
        for k, track in self.rigid:
            worst = max(worst, track.max_displacement(box_corners(instances[k].vertices)))
        for _, motion in self.deforming:
            worst = max(worst, motion)
        if self.sensor is not None:
            worst = max(worst, self.sensor.max_displacement(np.zeros((1, 3))))
        return worst


def classify(sweep, period, instances, mobility, sensor):
    """Sample the sweep and say what moves (a ``SweepMotion``); nothing is sampled when
    nothing may move."""
    cand = list(mobility.candidates)
    if not cand and not mobility.sensor_moves:
        return SweepMotion()
    times, mats, verts, sensor_mats, decomposed = sample_sweep(
        sweep, period, instances, cand, mobility.deformable, sensor, mobility.sensor_moves)
    out = SweepMotion(times=times, samples=len(times))
    # which bodies moved: every candidate's samples against its first, at once
    stack = np.array([mats[k] for k in cand], np.float64).reshape(len(cand), len(times), 4, 4)
    moved = np.abs(stack - stack[:, :1]).max(axis=(1, 2, 3), initial=0.0) > 1e-12
    kinds = {}
    for k, m in zip(cand, moved):
        deform = deformation(verts[k]) if k in verts else 0.0
        if deform > 1e-9 or m:
            kinds[k] = deform
    sensor_moved = (sensor_mats is not None
                    and np.abs(sensor_mats - sensor_mats[0]).max() > 1e-12)
    # the tracks of every body that moved, made together (Track.many: Track's own) of
    # the decompositions made as they were sampled
    parts = None if decomposed is None or not kinds else tuple(
        np.array([decomposed[k][i] for k in kinds]) for i in (0, 1))
    for (k, deform), track in zip(kinds.items(),
                                  Track.many(times, [mats[k] for k in kinds], parts)):
        out.tracks[k] = track
        if deform > 1e-9:
            inst = instances[k]
            out.deforming.append((k, deform + track.max_displacement(box_corners(inst.vertices))))
        else:
            out.rigid.append((k, track))
    if sensor_moved:
        out.sensor = Track(times, sensor_mats)
    return out
