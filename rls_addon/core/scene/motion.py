"""Motion over one sweep: poses sampled at a few times, interpolated per ray.

A ``Track`` holds 4x4 matrices at increasing times (seconds from the start of the
sweep). ``Track.at(t)`` interpolates per query time: translation by cubic Hermite
(finite-difference tangents), rotation by quaternion slerp, and the remaining
scale/shear part linearly; between samples this is exact for constant linear and
angular velocity. The Blender layer chooses the
samples (densifying until interpolation matches the evaluated animation).
"""

from dataclasses import dataclass

import numpy as np

from ..choices import MOTION
from ..errors import SettingsError


def quat_from_matrix(r):
    """Unit quaternions (w, x, y, z) of rotation matrices (..., 3, 3), by Shepperd's
    method (divide by the largest component, so no precision is lost near 0 or 180 deg)."""
    r = np.asarray(r, dtype=np.float64)
    shape = r.shape[:-2]
    r = r.reshape(-1, 3, 3)
    m00, m11, m22 = r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]
    trace = np.stack([m00 + m11 + m22, m00, m11, m22], axis=1)
    case = np.argmax(trace, axis=1)
    q = np.empty((len(r), 4))
    for c in range(4):
        sel = case == c
        if not sel.any():
            continue
        m = r[sel]
        if c == 0:
            s = 2.0 * np.sqrt(1.0 + m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2])
            q[sel] = np.stack([s / 4, (m[:, 2, 1] - m[:, 1, 2]) / s,
                               (m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 1, 0] - m[:, 0, 1]) / s], 1)
        elif c == 1:
            s = 2.0 * np.sqrt(1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2])
            q[sel] = np.stack([(m[:, 2, 1] - m[:, 1, 2]) / s, s / 4,
                               (m[:, 0, 1] + m[:, 1, 0]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s], 1)
        elif c == 2:
            s = 2.0 * np.sqrt(1.0 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2])
            q[sel] = np.stack([(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s,
                               s / 4, (m[:, 1, 2] + m[:, 2, 1]) / s], 1)
        else:
            s = 2.0 * np.sqrt(1.0 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2])
            q[sel] = np.stack([(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s,
                               (m[:, 1, 2] + m[:, 2, 1]) / s, s / 4], 1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(*shape, 4)


def matrix_from_quat(q):
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def slerp(q0, q1, a):
    """Spherical interpolation between unit quaternions, row-wise."""
    dot = np.einsum("ij,ij->i", q0, q1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    a = a[:, None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))[:, None]
    small = theta < 1e-9
    s = np.sin(theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        w0 = np.where(small, 1 - a, np.sin((1 - a) * theta) / s)
        w1 = np.where(small, a, np.sin(a * theta) / s)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def polar(linear):
    """Split 3x3 matrices A into a rotation R (det +1) and S = R^T A, so A = R S.

    R is the orthogonal matrix nearest to A (scale and shear go into S). For a
    mirroring A (det < 0) that matrix Q is a reflection, and R is Q with its second
    column negated: R keeps A's own x and z axes and S holds the mirror (on y). So a
    mirrored object keeps its forward (+X) and up (+Z), whichever axis its scale
    mirrors: a mirrored LiDAR looks along its own +X with its own +Z up, its +Y the
    mirror image of the object's."""
    u, _, vt = np.linalg.svd(linear)
    r = u @ vt
    flip = np.linalg.det(r) < 0
    if np.any(flip):
        r[flip, :, 1] *= -1
    return r, np.swapaxes(r, -1, -2) @ linear


def polar_parts(matrices):
    """(rotations, scale and shear): ``polar`` of the 3x3 parts of (..., 4, 4)
    ``matrices``, each shaped (..., 3, 3). Each matrix's the same bits however many
    are decomposed with it (numpy decomposes and multiplies them one by one), so a
    sweep decomposes each sample once, as it is read, and its tracks take them
    (``Track.many``'s ``parts``; tested against decomposing them together)."""
    m = np.asarray(matrices, dtype=np.float64)
    rot, scale = polar(m.reshape(-1, 4, 4)[:, :3, :3])
    shape = m.shape[:-2] + (3, 3)
    return rot.reshape(shape), scale.reshape(shape)


def rigid(matrices):
    """4x4 poses (one (4, 4) or a stack (N, 4, 4)) without their scale and shear: the
    3x3 replaced by ``polar``'s rotation, the translation kept."""
    m = np.asarray(matrices, dtype=np.float64)
    out = m.copy()
    out[..., :3, :3] = polar(m.reshape(-1, 4, 4)[:, :3, :3])[0].reshape(m.shape[:-2] + (3, 3))
    out[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    return out


def knot_velocities(positions, times):
    """(..., K, 3) finite-difference velocities (second order) of positions (..., K, 3)
    at knot times (K,): ``Track.velocities``, of one track or of M tracks sampled at
    the same times at once (``Track.many``), element for element the same."""
    p, t = positions, times
    if len(t) > 2:
        return np.gradient(p, t, axis=-2, edge_order=2)
    if len(t) == 2:
        return np.repeat(((p[..., 1, :] - p[..., 0, :]) / max(t[1] - t[0], 1e-300))[..., None, :],
                         2, axis=-2)
    return np.zeros_like(p)


def hermite(p0, v0, p1, v1, a, span):
    """Cubic Hermite between (p0, v0) and (p1, v1), row-wise, at fractions ``a`` of
    segments of length ``span`` (seconds)."""
    a = a[:, None]
    a2, a3 = a * a, a * a * a
    dt = span[:, None]
    return ((2 * a3 - 3 * a2 + 1) * p0 + (a3 - 2 * a2 + a) * dt * v0
            + (3 * a2 - 2 * a3) * p1 + (a3 - a2) * dt * v1)


@dataclass
class Track:
    """Poses of one body over a sweep.

    times     (K,) float64 increasing seconds since the start of the sweep
    matrices  (K, 4, 4) float64 world matrices at those times
    """

    times: np.ndarray
    matrices: np.ndarray

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        self.matrices = np.asarray(self.matrices, dtype=np.float64).reshape(-1, 4, 4)

    def __getattr__(self, name):
        """``_quat`` and ``_scale``, the knots' rotations (unit quaternions, each on the
        side of the one before) and scale and shear parts (``polar``), worked out when
        first asked for: a track that never turns its rays or interpolates a rotation
        (an object that stood still, given a one-knot track for its box each frame)
        never pays for the decomposition (0.1 ms a track)."""
        if name not in ("_quat", "_scale") or "matrices" not in self.__dict__:
            raise AttributeError(name)
        rot, scale = polar(self.matrices[:, :3, :3])
        quat = quat_from_matrix(rot)
        for k in range(1, len(quat)):  # keep neighbouring quaternions on one side
            if np.dot(quat[k - 1], quat[k]) < 0:
                quat[k] = -quat[k]
        self._quat, self._scale = quat, scale
        return quat if name == "_quat" else scale

    @classmethod
    def fixed(cls, matrix):
        return cls(np.zeros(1), np.asarray(matrix, np.float64)[None])

    @classmethod
    def many(cls, times, matrices, parts=None):
        """[Track] of M bodies sampled at the same ``times`` ((M, K, 4, 4)
        ``matrices``): each what ``Track(times, matrices[m])`` gives, byte for byte,
        their decompositions made together (a sweep's traffic: dozens of bodies).
        ``parts``: the matrices' ``polar_parts`` when they were made already (a
        sweep's samples, decomposed as they were read)."""
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, len(times), 4, 4)
        if not len(m):
            return []
        rot, scale = (np.asarray(a, np.float64).reshape(-1, 3, 3)
                      for a in (polar_parts(m) if parts is None else parts))
        quat = quat_from_matrix(rot).reshape(len(m), len(times), 4)
        scale = scale.reshape(len(m), len(times), 3, 3)
        for k in range(1, len(times)):  # neighbouring quaternions on one side, as one by one
            dot = np.einsum("ij,ij->i", quat[:, k - 1], quat[:, k])
            for j in np.nonzero(np.abs(dot) < 1e-9)[0]:  # too near 0 to trust its sign
                dot[j] = np.dot(quat[j, k - 1], quat[j, k])
            quat[dot < 0, k] *= -1.0
        velocity = knot_velocities(m[:, :, :3, 3], times)
        static = np.all(m == m[:, :1], axis=(1, 2, 3))  # is_static of each, at once
        out = []
        for j in range(len(m)):
            track = cls.__new__(cls)
            track.times, track.matrices = times, m[j]
            track._scale, track._quat, track._velocity = scale[j], quat[j], velocity[j]
            track._static = bool(static[j])
            out.append(track)
        return out

    @property
    def is_rigid(self):
        """Unit scale and no shear at every knot, to the float32 precision of Blender's
        matrices (1e-5): its rotation at any time is its slerped quaternion, and the
        polar decomposition of ``at`` gives that back."""
        if getattr(self, "_rigid", None) is None:
            self._rigid = bool(np.abs(self._scale - np.eye(3)).max() <= 1e-5)
        return self._rigid

    def rotate(self, t, vectors):
        """(N, 3) ``R(t_i) v_i``: each vector turned by the track's rotation at its own
        time, for a rigid track (``is_rigid``), without a matrix per time. Within a
        knot interval the slerp from q0 to q1 is q0 followed by a turn about one fixed
        axis by the fraction of the interval's angle, applied to each vector by
        Rodrigues' formula; then the interval's first rotation. Equal to
        ``sensor_axes(self.at(t))[1] @ v`` to rounding (tested), at a tenth of the
        cost for a spinning lidar whose every channel fires at its own time."""
        v = np.asarray(vectors, np.float64).reshape(-1, 3)
        if len(self.times) == 1 or self.is_static:
            return v @ matrix_from_quat(self._quat[0]).T
        i, a, _ = self._segments(t)
        axes, angles, starts = self._turns()
        out = np.empty_like(v)
        for seg in np.unique(i):  # a few knot intervals a sweep: one axis and start each
            sel = np.nonzero(i == seg)[0] if len(axes) > 1 else slice(None)
            kx, ky, kz = axes[seg]
            phi = angles[seg] * a[sel]
            c, s = np.cos(phi), np.sin(phi)
            vx, vy, vz = v[sel, 0], v[sel, 1], v[sel, 2]
            kv = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
            turned = np.empty((len(phi), 3))
            turned[:, 0] = vx * c + (ky * vz - kz * vy) * s + kx * kv
            turned[:, 1] = vy * c + (kz * vx - kx * vz) * s + ky * kv
            turned[:, 2] = vz * c + (kx * vy - ky * vx) * s + kz * kv
            out[sel] = turned @ starts[seg].T
        return out

    def _turns(self):
        """Per knot interval: the unit axis and angle of the turn from its first
        rotation to its last (q0* q1), and its first rotation matrix."""
        if getattr(self, "_turn_cache", None) is None:
            q0, q1 = self._quat[:-1], self._quat[1:]
            w0, x0, y0, z0 = q0.T
            w1, x1, y1, z1 = q1.T
            rel = np.stack([w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1,   # conj(q0) * q1
                            w0 * x1 - x0 * w1 - y0 * z1 + z0 * y1,
                            w0 * y1 + x0 * z1 - y0 * w1 - z0 * x1,
                            w0 * z1 - x0 * y1 + y0 * x1 - z0 * w1], 1)
            rel[rel[:, 0] < 0] *= -1.0  # the shorter way, as slerp takes it
            sine = np.linalg.norm(rel[:, 1:], axis=1)
            angle = 2.0 * np.arctan2(sine, rel[:, 0])
            axis = np.where(sine[:, None] > 0, rel[:, 1:] / np.where(sine > 0, sine, 1.0)[:, None],
                            np.array([1.0, 0.0, 0.0]))
            self._turn_cache = (axis, angle, matrix_from_quat(q0))
        return self._turn_cache

    @property
    def is_static(self):
        """Every knot's matrix the first's (asked for every track a few times a frame:
        worked out once, as ``is_rigid``; a track's knots are not changed once made)."""
        if getattr(self, "_static", None) is None:
            self._static = bool(np.all(self.matrices == self.matrices[0]))
        return self._static

    def at(self, t):
        """(N, 4, 4) matrices at times t (clamped to the sampled span)."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        out = np.empty((t.shape[0], 4, 4))
        out[:] = np.eye(4)
        if len(self.times) == 1 or self.is_static:
            out[:] = self.matrices[0]
            return out
        i, a, span = self._segments(t)
        out[:, :3, 3] = self._hermite(i, a, span)
        rot = matrix_from_quat(slerp(self._quat[i], self._quat[i + 1], a))
        scale = self._scale[i] * (1 - a)[:, None, None] + self._scale[i + 1] * a[:, None, None]
        out[:, :3, :3] = rot @ scale
        return out

    def positions_at(self, t):
        """(N, 3) translations at times t: ``at(t)[:, :3, 3]`` without the rotations
        (a track whose ``linear_is_constant`` needs no more)."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        if len(self.times) == 1 or self.is_static:
            return np.repeat(self.matrices[:1, :3, 3], len(t), axis=0)
        return self._hermite(*self._segments(t))

    def _segments(self, t):
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        k = len(self.times)
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, k - 2)
        span = self.times[i + 1] - self.times[i]
        a = np.clip((t - self.times[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
        return i, a, span

    @property
    def linear_is_constant(self):
        """True when only the translation changes (a car driving straight, a sliding door)."""
        lin = self.matrices[:, :3, :3]
        return bool(np.all(lin == lin[0]))

    def inverse_at(self, t):
        """World-to-local maps at times t: (A, b) with x_local = A x_world + b, A (N, 3, 3)
        or one shared (3, 3) when the rotation and scale never change (then no per-ray
        matrix is built at all)."""
        if len(self.times) == 1 or self.is_static:
            inv = np.linalg.inv(self.matrices[0])
            return inv[:3, :3], np.broadcast_to(inv[:3, 3], (np.size(t), 3))
        i, a, span = self._segments(t)
        trans = self._hermite(i, a, span)
        if self.linear_is_constant:
            a_inv = np.linalg.inv(self.matrices[0, :3, :3])
            return a_inv, -trans @ a_inv.T
        rot = matrix_from_quat(slerp(self._quat[i], self._quat[i + 1], a))
        scale = self._scale[i] * (1 - a)[:, None, None] + self._scale[i + 1] * a[:, None, None]
        rt = np.swapaxes(rot, 1, 2)
        if np.allclose(self._scale, np.eye(3), atol=1e-12):
            a_inv = rt
        else:
            a_inv = np.linalg.inv(scale) @ rt
        return a_inv, -np.einsum("nij,nj->ni", a_inv, trans)

    def rays_to_local(self, t, origins, directions):
        """Rays o + s d (world; ``origins`` one (1, 3) or one per ray) carried into the
        object's frame at times ``t``: (local origins, local directions, the linear map
        A of ``inverse_at``, shared (3, 3) or per ray). The ray parameter s is kept,
        so a hit at s in the object's frame lies s along the world ray."""
        a, b = self.inverse_at(t)
        d = np.asarray(directions, np.float64)
        if a.ndim == 2:  # one linear map for every ray: no per-ray matrices
            return origins @ a.T + b, d @ a.T, a
        o = np.broadcast_to(origins, d.shape)
        return np.einsum("nij,nj->ni", a, o) + b, np.einsum("nij,nj->ni", a, d), a

    @property
    def velocities(self):
        """(K, 3) finite-difference velocities at the samples (second order), cached."""
        v = self.__dict__.get("_velocity")
        if v is None:
            v = self._velocity = knot_velocities(self.matrices[:, :3, 3], self.times)
        return v

    def _hermite(self, i, a, span):
        """Translation by cubic Hermite interpolation with finite-difference tangents
        (exact for constant velocity, O(dt^4) for smooth motion: far fewer samples than
        linear interpolation for eased keyframes)."""
        p, v = self.matrices[:, :3, 3], self.velocities
        segments = np.unique(i)
        if len(segments) * 64 > len(i):
            return hermite(p[i], v[i], p[i + 1], v[i + 1], a, span)
        # few intervals, many times (a ray per firing time): each interval's knots
        # broadcast instead of gathered per time; the same arithmetic, the same bytes
        out = np.empty((len(i), 3))
        for seg in segments:
            sel = np.nonzero(i == seg)[0]
            out[sel] = hermite(p[seg][None], v[seg][None], p[seg + 1][None], v[seg + 1][None],
                               a[sel], span[sel])
        return out

    def max_displacement(self, points):
        """Largest distance any of ``points`` (local coordinates) travels between the
        first and any later sample."""
        p = np.c_[np.asarray(points, np.float64).reshape(-1, 3), np.ones(len(points))]
        w = np.einsum("kij,nj->kni", self.matrices[:, :3, :], p)
        return float(np.linalg.norm(w - w[:1], axis=2).max()) if len(p) else 0.0


def effective_times(times, period, mode, substeps):
    """Scene time at which each ray sees the world.

    exact     the ray's own time
    substeps  the middle of its sub-sweep of period/N (the paper's N partial sweeps,
              error at most v*T/(2N))
    snapshot  the start of the sweep (one scene state per frame, as CARLA)

    ``substeps`` is N >= 1 (the scan chooses N first when the user asked for 0:
    ``sweep.substep_count``)."""
    t = np.asarray(times, dtype=np.float64)
    MOTION.check(mode)
    if mode == "exact":
        return t
    if mode == "snapshot":
        return np.zeros_like(t)
    n = int(substeps)
    if n < 1:
        raise SettingsError(f"sub-steps must be at least 1 here, got {substeps}")
    step = period / n
    return (np.minimum(np.floor(t / step), n - 1) + 0.5) * step


KNOT_TOLERANCE_M = 5e-4  # pose knots: interpolation within half a millimetre


def pose_knots(track, tolerance_m=KNOT_TOLERANCE_M, reach_m=1.0):
    """Times and 4x4 rigid poses of a moving sensor's frame (its track without scale
    and shear, ``rigid``: the frame its points are in) at enough knots over its sweep
    that ``poses_at`` (linear translation, slerp rotation between knots) stays within
    ``tolerance_m`` of it, measured at the sensor and at ``reach_m`` along each axis (a
    rotation error shows as a distance there). What the sidecar carries so a
    sensor-frame cloud can be mapped to the world point by point."""
    lo, hi = float(track.times[0]), float(track.times[-1])
    probe = np.array([[0, 0, 0, 1], [reach_m, 0, 0, 1], [0, reach_m, 0, 1], [0, 0, reach_m, 1]],
                     float).T
    times = np.array([lo, hi]) if hi > lo else np.array([lo])
    mids = (times[1:] + times[:-1]) / 2
    # the ends and their midpoint in one evaluation (each row as on its own)
    first = rigid(track.at(np.concatenate([times, mids])))
    mats, at_mids = first[:len(times)], first[len(times):]
    while len(times) > 1:
        # each pose is evaluated once: the midpoints that fail become knots as they are
        if at_mids is None:
            mids = (times[1:] + times[:-1]) / 2
            at_mids = rigid(track.at(mids))
        err = np.linalg.norm((poses_at(times, mats, mids) - at_mids) @ probe, axis=1)
        bad = err.max(axis=1) > tolerance_m
        if not bad.any() or len(times) >= 4097:
            break
        order = np.argsort(np.concatenate([times, mids[bad]]), kind="stable")
        times = np.concatenate([times, mids[bad]])[order]
        mats = np.concatenate([mats, at_mids[bad]])[order]
        at_mids = None
    return times, mats


def poses_at(times, matrices, t):
    """(N, 4, 4) poses at times ``t`` from knots (``times`` increasing, ``matrices``
    (K, 4, 4) rigid): translation linear, rotation by slerp between neighbouring knots,
    clamped to the knots' span. The interpolation the sidecar's ``sensor_poses``
    state, in numpy (any quaternion library gives the same)."""
    times = np.asarray(times, np.float64).reshape(-1)
    m = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    t = np.asarray(t, np.float64).reshape(-1)
    out = np.empty((len(t), 4, 4))
    out[:] = np.eye(4)
    if len(times) == 1:
        out[:] = m[0]
        return out
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    span = times[i + 1] - times[i]
    a = np.clip((t - times[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    q = quat_from_matrix(m[:, :3, :3])
    out[:, :3, :3] = matrix_from_quat(slerp(q[i], q[i + 1], a))
    out[:, :3, 3] = m[i, :3, 3] * (1 - a)[:, None] + m[i + 1, :3, 3] * a[:, None]
    return out
