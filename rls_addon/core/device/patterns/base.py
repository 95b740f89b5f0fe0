"""The scan-pattern contract shared by every family."""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ...errors import PatternError


@dataclass(frozen=True)
class ScanPattern:
    """The rays of one frame, in firing order.

    directions  (N, 3) float64 unit vectors in the sensor frame (+X forward, +Y left, +Z up)
    times       (N,)   float64 seconds since the start of the frame, non-decreasing
    channels    (N,)   uint16 vendor channel / ring index
    period      float  frame period in seconds (times lie in [0, period))
    origins     (N, 3) float64 where each ray leaves from, in the sensor frame (metres), for
                devices whose beams leave from points off the sensor origin (Ouster's
                beam-origin ring, Velodyne's per-laser offsets); None: all from the origin
    """

    directions: np.ndarray
    times: np.ndarray
    channels: np.ndarray
    period: float
    origins: np.ndarray = None

    def __post_init__(self):
        d = self.directions
        if d.ndim != 2 or d.shape[1] != 3:
            raise PatternError(f"pattern directions must have shape (N, 3), got {d.shape}")
        n = d.shape[0]
        if self.times.shape != (n,) or self.channels.shape != (n,):
            raise PatternError("pattern times and channels must have one entry per direction")
        if self.origins is not None and self.origins.shape != (n, 3):
            raise PatternError(f"pattern origins must have shape ({n}, 3), got "
                               f"{self.origins.shape}")
        if not (self.period > 0):
            raise PatternError(f"pattern period must be positive, got {self.period}")

    def __len__(self):
        return self.directions.shape[0]

    def rotated(self, rotation):
        """The directions turned by the 3x3 ``rotation`` (sensor to world), (N, 3); the
        last result is kept, so a sensor that does not move pays once per scan."""
        rotation = np.asarray(rotation, np.float64)
        last = self.__dict__.get("_rotated")
        if last is not None and np.array_equal(last[0], rotation):
            return last[1]
        out = self.directions @ rotation.T
        out.flags.writeable = False  # shared between frames
        self.__dict__["_rotated"] = (rotation.copy(), out)
        return out

    def placed_origins(self, rotation, position):
        """The rays' origins (``origins``) in the world for a sensor at ``position``
        turned by ``rotation``, (N, 3); the last result is kept and read-only, so a
        sensor that does not move gets the same array every frame (and its static
        cast can be reused, see ``StaticScene.reusable``)."""
        rotation = np.asarray(rotation, np.float64)
        position = np.asarray(position, np.float64).reshape(3)
        last = self.__dict__.get("_placed")
        if last is not None and np.array_equal(last[0], rotation) \
                and np.array_equal(last[1], position):
            return last[2]
        out = self.origins @ rotation.T + position
        out.flags.writeable = False
        self.__dict__["_placed"] = (rotation.copy(), position.copy(), out)
        return out

    def started_at(self, azimuth_deg):
        """A spinning pattern whose sweep starts at ``azimuth_deg`` (sensor frame,
        counter-clockwise from +X) instead of its head's forward direction: every
        direction turned about the sensor's z axis, times unchanged. The seam between
        one sweep and the next (where an object is scanned at the start and the end of
        the sweep, a sweep period apart) then lies there. Kept per angle, read-only."""
        angle = float(azimuth_deg) % 360.0
        if angle == 0.0:
            return self
        cache = self.__dict__.setdefault("_started", {})
        got = cache.get(angle)
        if got is None:
            a = np.radians(angle)
            c, s = np.cos(a), np.sin(a)
            turn = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
            d = self.directions @ turn
            d.flags.writeable = False
            o = None
            if self.origins is not None:
                o = self.origins @ turn
                o.flags.writeable = False
            got = cache[angle] = ScanPattern(d, self.times, self.channels, self.period, o)
        return got

    @cached_property
    def trace_order(self):
        """A permutation of the rays that keeps neighbours in direction next to each
        other (a Z-order curve over azimuth and elevation), for backends that trace
        rays in 16-ray packets (Embree); None when the firing order is coherent enough
        already. Computed once.

        Only worth it where consecutive rays point far apart: measured on the benchmark
        street, RoboSense M1 (packets spanning 53 deg in firing order, 1.2 deg in
        Z-order) cast 8.6 -> 5.8 ms, while Pandar64 and Pandar128 (7-9 deg) got 7-10%
        slower from the scattered reads and writes."""
        if len(self) < 2 * _PACKET or _packet_spread_deg(self.directions) <= _COHERENT_DEG:
            return None
        return z_order(*angles_from_directions(self.directions))

    @cached_property
    def columns(self):
        """The directions as a contiguous (3, N) array (x, y and z rows): gathering
        one coordinate of many rays then reads one contiguous row."""
        return np.ascontiguousarray(self.directions.T)


def directions_from_angles(azimuth_rad, elevation_rad):
    """Unit vectors for azimuth (from +X towards +Y, counter-clockwise seen from above)
    and elevation (up from the XY plane), both in radians. Returns (N, 3) float64."""
    az = np.asarray(azimuth_rad, dtype=np.float64)
    el = np.asarray(elevation_rad, dtype=np.float64)
    ce = np.cos(el)
    return np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=-1)


def angles_from_directions(directions):
    """Inverse of ``directions_from_angles``: (azimuth, elevation) in radians."""
    d = np.asarray(directions, dtype=np.float64)
    az = np.arctan2(d[:, 1], d[:, 0])
    el = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    return az, el


_PACKET = 16
_COHERENT_DEG = 20.0


def _packet_spread_deg(directions):
    """Mean over 16-ray packets (in firing order) of the largest angle between a ray
    and its packet's mean direction, in degrees."""
    n = len(directions) // _PACKET * _PACKET
    p = directions[:n].reshape(-1, _PACKET, 3)
    m = p.mean(axis=1, keepdims=True)
    m /= np.maximum(np.linalg.norm(m, axis=2, keepdims=True), 1e-300)
    cos = np.clip(np.einsum("pkj,pkj->pk", p, np.broadcast_to(m, p.shape)), -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min(axis=1))).mean())


def z_order(u, v, bits=10):
    """Indices sorting points (u, v) along a Z-order (Morton) curve over their
    bounding box, at ``bits`` bits per axis."""
    def cells(x):
        x = np.asarray(x, np.float64)
        span = float(np.ptp(x)) if x.size else 0.0
        q = (x - (x.min() if x.size else 0.0)) * (((1 << bits) - 1) / span if span > 0 else 0.0)
        return np.clip(q, 0, (1 << bits) - 1).astype(np.uint64)

    def spread(x):  # bit k of x goes to bit 2k
        out = np.zeros_like(x)
        for k in range(bits):
            out |= ((x >> np.uint64(k)) & np.uint64(1)) << np.uint64(2 * k)
        return out

    key = spread(cells(u)) | (spread(cells(v)) << np.uint64(1))
    return np.argsort(key, kind="stable")
