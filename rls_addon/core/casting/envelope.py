"""Which way boxes lie, seen from one point: per azimuth sector, the span of elevations
(as slopes, rise over horizontal run) any of a set of axis-aligned boxes covers. A ray
whose slope lies outside its sector's span meets none of the boxes.

The watertight wrapper uses it for backends that pay per ray (BVHTree): from a sensor
above a ground plane, rays that go down slightly but pass beyond the ground's edge are
told apart from rays that may meet something, without casting them (the octant test
of ``WatertightCaster.may_reach_hull`` sees one box per octant, from the ground to
the tallest object, and lets them through).
"""

import numpy as np

SECTORS = 1024  # azimuth sectors of 0.35 degrees
_MARGIN = 1e-9  # radians and relative slope: rounding never moves a ray out of a span


class ElevationEnvelope:
    """The slope span per azimuth sector of boxes ``lo``, ``hi`` ((K, 3) each) seen
    from ``origin`` (3,); ``may_meet`` tests rays from that origin."""

    def __init__(self, origin, lo, hi, sectors=SECTORS):
        self.origin = np.asarray(origin, np.float64).reshape(3)
        self.sectors = int(sectors)
        lo, hi = lo - self.origin, hi - self.origin
        near, far = _horizontal_reach(lo, hi)
        s_lo, s_hi = _slope_span(lo[:, 2], hi[:, 2], near, far)
        self.low = np.full(self.sectors, np.inf)
        self.high = np.full(self.sectors, -np.inf)
        first, count = self._sector_spans(lo, hi, near)
        sector = (np.repeat(first, count) + _ranges(count)) % self.sectors
        np.minimum.at(self.low, sector, np.repeat(s_lo, count))
        np.maximum.at(self.high, sector, np.repeat(s_hi, count))

    def may_meet(self, directions):
        """(N,) bool: False for rays (from the origin) that surely meet no box."""
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        x, y, z = d[:, 0], d[:, 1], d[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = z / np.sqrt(x * x + y * y)  # +-inf straight up or down
        k = self._sector(np.arctan2(y, x))
        return ~((slope < self.low.take(k)) | (slope > self.high.take(k)))

    def _sector(self, azimuth):
        """The sector of each azimuth (radians; any, wrapped)."""
        k = np.floor((azimuth + np.pi) * (self.sectors / (2 * np.pi))).astype(np.int64)
        if k.size and (k.min() < 0 or k.max() >= self.sectors):
            k %= self.sectors
        return k

    def _sector_spans(self, lo, hi, near):
        """Per box: its first azimuth sector and how many it covers (every sector for
        a box standing over or under the origin)."""
        x = np.stack([lo[:, 0], hi[:, 0], hi[:, 0], lo[:, 0]], axis=1)
        y = np.stack([lo[:, 1], lo[:, 1], hi[:, 1], hi[:, 1]], axis=1)
        az = np.arctan2(y, x)
        # A box beside the origin spans less than half a turn: its corners' angles,
        # taken relative to its first corner's, give its extent without a wrap.
        rel = (az - az[:, :1] + np.pi) % (2 * np.pi) - np.pi
        a0 = az[:, 0] + rel.min(axis=1) - _MARGIN
        a1 = az[:, 0] + rel.max(axis=1) + _MARGIN
        first = self._sector(a0)
        count = (self._sector(a1) - first) % self.sectors + 1
        # Over or under the origin, or so close beside it that a corner's angle may
        # have wrapped: every sector.
        around = (near == 0) | (rel.max(axis=1) - rel.min(axis=1) > 0.75 * np.pi)
        first[around], count[around] = 0, self.sectors
        return first, count


def _horizontal_reach(lo, hi):
    """Nearest and farthest horizontal distance from the origin to each box (offsets
    ``lo``, ``hi`` from the origin); nearest 0 for a box over or under it."""
    gap = np.maximum(np.maximum(lo[:, :2], -hi[:, :2]), 0.0)
    span = np.maximum(np.abs(lo[:, :2]), np.abs(hi[:, :2]))
    return np.sqrt((gap * gap).sum(axis=1)), np.sqrt((span * span).sum(axis=1))


def _slope_span(z_lo, z_hi, near, far):
    """Lowest and highest slope from the origin into each box: the top seen at its
    nearest (above the origin) or farthest (below) horizontal distance, the bottom
    the other way round; widened by a relative margin."""
    with np.errstate(divide="ignore", invalid="ignore"):
        top = np.where(z_hi >= 0, z_hi / near, z_hi / far)
        bottom = np.where(z_lo <= 0, z_lo / near, z_lo / far)
    top = np.where(np.isnan(top), np.inf, top)           # 0 / 0: the origin's level
    bottom = np.where(np.isnan(bottom), -np.inf, bottom)
    return (bottom - _MARGIN * (1 + np.abs(bottom)), top + _MARGIN * (1 + np.abs(top)))


def _ranges(count):
    """0..c-1 for each c in ``count``, concatenated."""
    ends = np.cumsum(count)
    return np.arange(ends[-1]) - np.repeat(ends - count, count) if len(count) else \
        np.zeros(0, np.int64)
