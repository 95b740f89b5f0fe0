"""Where a frame's rays go in the world: each ray's origin, direction and time in the
scene from the pattern and the sensor's pose or track (``_Aim``), and the sensor's
axes and frame from its object's matrix."""

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..scene.motion import polar, rigid
from ..scene.track_set import positions_at as track_positions


def distinct_times(times):
    """``np.unique(times, return_inverse=True)``, in one pass when the times do not
    decrease (a pattern's firing order, and its sub-step times): no sort."""
    t = np.asarray(times)
    if len(t) and np.all(t[1:] >= t[:-1]):
        first = np.empty(len(t), bool)
        first[0] = True
        np.not_equal(t[1:], t[:-1], out=first[1:])
        return t[first], np.cumsum(first) - 1
    return np.unique(t, return_inverse=True)


def first_of_each(times):
    """Indices of the first ray of each distinct time, in the order of the times
    (``distinct_times``' distinct times are ``times[first_of_each(times)]``)."""
    t = np.asarray(times)
    if len(t) and np.all(t[1:] >= t[:-1]):
        first = np.empty(len(t), bool)
        first[0] = True
        np.not_equal(t[1:], t[:-1], out=first[1:])
        return np.nonzero(first)[0]
    return np.unique(t, return_index=True)[1]


def sensor_axes(sensor_to_world):
    """Origins and orthonormal rotations of 4x4 poses (one (4, 4) or a stack (N, 4, 4));
    scale and shear are removed (``motion.polar``). A mirrored sensor (a negative scale
    on any axis) looks along its own +X with its own +Z up: the mirror flips its +Y
    only. A single pose's answer is kept (``_AXES``, a few poses): a still sensor asks with the
    same pose every frame, and the decomposition costs 0.2 ms."""
    m = np.asarray(sensor_to_world, dtype=np.float64)
    key = m.tobytes() if m.shape == (4, 4) else None
    got = _AXES.get(key) if key is not None else None
    if got is None:
        rot, _ = polar(m.reshape(-1, 4, 4)[:, :3, :3])
        got = m[..., :3, 3].copy(), rot.reshape(m.shape[:-2] + (3, 3))
        if key is None:
            return got
        if len(_AXES) >= 16:
            _AXES.clear()
        _AXES[key] = got
    return got[0].copy(), got[1].copy()


_AXES = {}

# A LiDAR axis shorter than this share of its longest has zero scale: it has no axes.
ZERO_SCALE = 1e-9
# Its axes' cosines beyond this (0.006 degrees from a right angle, far above the float32
# rounding of Blender's matrices): sheared, no sensor frame.
MAX_SHEAR_COS = 1e-4


def sensor_frame(matrix, sensor="sensor"):
    """The 4x4 rigid pose(s) of a sensor's frame from its object's world matrix (one
    (4, 4) or a stack (N, 4, 4)): its origin and ``sensor_axes``' rotation (``rigid``), the pose
    that maps its sensor-frame points to the world (the sidecar's). ``SceneError``
    naming ``sensor`` when a matrix is not finite or scales an axis to nothing."""
    m = np.asarray(matrix, dtype=np.float64)
    stack = m.reshape(-1, 4, 4)
    if not np.isfinite(stack).all():
        raise SceneError(f"LiDAR '{sensor}' has a position, rotation or scale that is not "
                         "a finite number: set its transform (and its parents') to numbers")
    lengths = np.linalg.norm(stack[:, :3, :3], axis=1)
    sv = np.linalg.svd(stack[:, :3, :3], compute_uv=False)
    zero = ~(sv[:, -1] > ZERO_SCALE * sv[:, 0])
    if zero.any():
        k = int(np.argmax(zero))
        axes = ", ".join(f"{v:g}" for v in lengths[k])
        raise SceneError(f"LiDAR '{sensor}' has zero scale on an axis: its axes have lengths "
                         f"({axes}) in the world, so it has no sensor frame; give every "
                         "scale value of it (and of its parents) a non-zero size")
    # Its axes at right angles (scaled along them, or mirrored, they still are): a
    # sheared matrix, as under a parent scaled unevenly along axes turned from the
    # LiDAR's, has no one sensor frame, and its field-of-view outline is drawn sheared.
    unit = stack[:, :3, :3] / lengths[:, None, :]
    cos = np.abs(np.einsum("nij,nik->njk", unit, unit) - np.eye(3)).max(axis=(1, 2))
    sheared = ~(cos <= MAX_SHEAR_COS)
    if sheared.any():
        k = int(np.argmax(sheared))
        c = unit[k]
        angles = [float(np.degrees(np.arccos(np.clip(abs(c[:, i] @ c[:, j]), 0.0, 1.0))))
                  for i, j in ((0, 1), (0, 2), (1, 2))]
        raise SceneError(
            f"LiDAR '{sensor}' is sheared: its axes are not at right angles in the world "
            f"(X-Y {angles[0]:.1f}, X-Z {angles[1]:.1f}, Y-Z {angles[2]:.1f} degrees), as "
            "under a parent scaled unevenly along axes turned from the LiDAR's, so it has "
            "no one sensor frame; apply the parent's scale (Object > Apply > Scale) or "
            "clear the LiDAR's parent keeping its transform")
    return rigid(m)


@dataclass
class _Aim:
    """The rays of a frame in the world: origins ((1, 3) for a still sensor, else one
    per ray), directions, their times in the scene (``tscene``), trace order, columns,
    channels and firing times, and the sensor's distinct poses."""

    origins: np.ndarray
    dirs: np.ndarray
    times: np.ndarray
    order: np.ndarray
    columns: tuple
    channels: np.ndarray
    ray_times: np.ndarray
    _poses: object  # (P, 3) the distinct poses, or a _DistinctPoses that makes them
    beam_origins: np.ndarray = None  # (N, 3) sensor frame, or None: all from the origin

    @classmethod
    def of(cls, pattern, sensor_to_world, sensor_track, tscene, centre=None):
        """``centre``: the prepared scene's, when known (a moving sensor's origins come
        centred on it too, for its cast: ``track_set.positions_at``)."""
        dirs_sensor = pattern.directions
        beam = pattern.origins  # (N, 3) sensor frame or None: the rays leave the origin
        if sensor_track is None or sensor_track.is_static:
            origin, rot = sensor_axes(sensor_to_world if sensor_track is None
                                      else sensor_track.matrices[0])
            origins = origin.reshape(1, 3)
            dirs = pattern.rotated(rot)
            poses = origins
            if beam is not None:
                origins = pattern.placed_origins(rot, origin)
        elif sensor_track.linear_is_constant:
            # Driving without turning: one rotation for the sweep (the pattern turned
            # once, and kept while it does not turn), an origin per firing time (in C,
            # see track_set.positions_at; the distinct poses only when asked for).
            origins = track_positions(sensor_track, tscene, None if beam is not None
                                      else centre)
            poses = _DistinctPoses(origins, tscene)
            rot = sensor_axes(sensor_track.matrices[0])[1]
            dirs = pattern.rotated(rot)
            if beam is not None:
                origins = origins + beam @ rot.T
        elif sensor_track.is_rigid:
            # Turning without scale or shear: each ray turned by the rotation at its own
            # firing time, by the track's turn within its knot interval (``Track.rotate``,
            # no matrix per time: with every channel at its own time, a matrix and its
            # polar decomposition per ray cost 240 ms a Pandar64 frame).
            origins = track_positions(sensor_track, tscene, None if beam is not None
                                      else centre)
            poses = _DistinctPoses(origins, tscene)
            dirs = sensor_track.rotate(tscene, dirs_sensor)
            if beam is not None:
                origins = origins + sensor_track.rotate(tscene, beam)
        else:
            # One pose per distinct firing time (the channels of a firing share it, where
            # the device fires them together), scale and shear taken apart.
            times, at = distinct_times(tscene)
            poses, rots = sensor_axes(sensor_track.at(times))
            origins = poses[at]
            dirs = np.einsum("nij,nj->ni", rots[at], dirs_sensor)
            if beam is not None:
                origins = origins + np.einsum("nij,nj->ni", rots[at], beam)
        return cls(origins, dirs, tscene, pattern.trace_order, pattern.columns,
                   pattern.channels, pattern.times, poses, beam)

    def pose_points(self):
        """The sensor's poses, as many times as its rays share them (what a covering
        check needs, without finding the distinct ones)."""
        p = self._poses
        return p.positions if isinstance(p, _DistinctPoses) else p

    @property
    def poses(self):
        """The sensor's distinct poses over the sweep ((1, 3) for a still sensor)."""
        p = self._poses
        if isinstance(p, _DistinctPoses):
            p = self._poses = p()
        return p

    def subset(self, pick):
        """The rays ``pick`` (a ``_Subset``) chooses, in the pattern's trace order."""
        return _Aim(self.origins if self.origins.shape[0] == 1 else pick(self.origins),
                    pick(self.dirs), pick(self.times), pick.order,
                    tuple(pick(c) for c in self.columns), pick(self.channels),
                    pick(self.ray_times), self.poses, pick(self.beam_origins))


class _DistinctPoses:
    """The sensor's positions at its distinct firing times, from its position at every
    ray's time (what ``_Aim.poses`` holds; made only when asked for: the rays carry
    their origins, and a prepared scene checks them all at once)."""

    def __init__(self, positions, times):
        self.positions, self.times = positions, times

    def __call__(self):
        return self.positions[first_of_each(self.times)]
