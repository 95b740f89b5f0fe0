"""A frame's rays grouped by direction, so that every ground-truth box looks only at
the rays (and the points on them) that may come near it, all boxes in one go.

The rays' unit directions are put in cells of azimuth (``AZ_CELLS`` over 360 deg) and
elevation (``EL_CELLS`` over 180 deg) by two stable radix sorts, once per frame, and
kept while a sensor casts the very same direction array again (a still sensor, or one
driving without turning: ``ScanPattern.rotated`` gives one read-only array). A box's
cone from the middle of the ray origins ``o0`` (half-angle asin(reach / distance), its reach the
box's radius plus how far a moving sensor's origins lie from the apex) holds every ray that passes
within that radius of its centre: such a direction lies within the cone's angle of its
axis, so within that angle of its elevation and within asin(sin a / cos e) of its
azimuth (the span of a spherical cap that holds no pole). The cells those spans touch
are a superset; where a cone would hold a pole, or ``o0`` lies inside the reach, every
ray is taken, or for a box wholly below or above every origin (a sensor on its own
car's roof) the elevation bands that can reach it (``RayCells._bands``). A point lies
on its ray (``RayRecord.point_world``), so the points near a box are the points of the
rays near it.
"""

import math

import numpy as np

from ..native.vectors import column_bounds

AZ_CELLS = 720   # half-degree sectors of azimuth
EL_CELLS = 360   # half-degree bands of elevation
PAD = 1e-9       # radians added to every span (rounding of atan2 and asin)
SEGMENT = 4096   # rays in one run of a box's candidates, at most

_KEPT = [None]   # (directions array, its _Cells): the last frame's, for the same array


class _Cells:
    """Directions sorted by (azimuth sector, elevation band): ``order`` and each cell's
    first row in it (``starts``)."""

    def __init__(self, dirs):
        d = np.asarray(dirs, np.float64).reshape(-1, 3)
        self.n = len(d)
        az = np.arctan2(d[:, 1], d[:, 0])
        el = np.arcsin(np.clip(d[:, 2], -1.0, 1.0))
        sector = _cell(az, -math.pi, AZ_CELLS / (2 * math.pi), AZ_CELLS).astype(np.int16)
        band = _cell(el, -math.pi / 2, EL_CELLS / math.pi, EL_CELLS).astype(np.int16)
        order = np.argsort(band, kind="stable")  # radix sorts: 16-bit keys
        self.order = order[np.argsort(sector[order], kind="stable")]
        cell = sector.astype(np.int64) * EL_CELLS + band
        self.starts = np.zeros(AZ_CELLS * EL_CELLS + 1, np.int64)
        np.cumsum(np.bincount(cell, minlength=AZ_CELLS * EL_CELLS), out=self.starts[1:])

    @classmethod
    def of(cls, dirs):
        """The cells of ``dirs``, kept for the next call with the same read-only array
        (whose contents cannot change)."""
        kept = _KEPT[0]
        if kept is not None and kept[0] is dirs:
            return kept[1]
        got = cls(dirs)
        if isinstance(dirs, np.ndarray) and not dirs.flags.writeable:
            _KEPT[0] = (dirs, got)
        return got


def _cell(angle, low, scale, count):
    return np.clip(np.floor((angle - low) * scale), 0, count - 1)


def _cell1(angle, low, scale, count):
    """``_cell`` of one angle."""
    return min(max(int(math.floor((angle - low) * scale)), 0), count - 1)


def _ranges(lo, hi):
    """(owner, index) of every index in the ranges [lo[j], hi[j]): ``owner`` j."""
    n = np.maximum(hi - lo, 0)
    total = int(n.sum())
    owner = np.repeat(np.arange(len(lo)), n)
    if not total:
        return owner, np.zeros(0, np.int64)
    first = np.cumsum(n) - n
    return owner, np.arange(total, dtype=np.int64) - np.repeat(first - lo, n)


def _runs(starts, spans, owner):
    """(lo, hi, owner) arrays of the runs of ``cells.order`` that cell spans [(sector
    lo, sector hi, band lo, band hi)] cover: one run per sector, each of ``owner``."""
    return _runs_of(starts, np.array(spans, np.int64).reshape(-1, 4),
                    np.full(len(spans), owner, np.int64))


def _runs_of(starts, spans, owners):
    """``_runs`` of many owners' spans at once: ``spans`` an (S, 4) array of (sector lo,
    sector hi, band lo, band hi), span s of ``owners[s]``; the runs in the order of the
    spans (one per sector, as ``_runs`` gives them span by span), in one pass of array
    steps instead of one per span."""
    span, sector = _ranges(spans[:, 0], spans[:, 1] + 1)
    sec = sector * EL_CELLS
    return (starts[sec + spans[span, 2]], starts[sec + spans[span, 3] + 1],
            np.asarray(owners, np.int64)[span])


class RayCells:
    """The rays of a ``RayRecord`` (and its points) by direction (see the module
    docstring)."""

    def __init__(self, rays):
        self.rays = rays
        o = np.asarray(rays.origins, np.float64)
        # The cones' apex: the middle of the origins' bounding box, and how far they may
        # lie from it (half its diagonal: at least the farthest origin's distance; the
        # cones widen by it). One origin: itself.
        self.o0, self.travel = (o[0] if len(o) else np.zeros(3)), 0.0
        self.o_lo = self.o_hi = self.o0
        self.sideways = 0.0  # how far the origins may lie from o0 across (x, y)
        if len(o) > 1:
            lo, hi = column_bounds(rays.origins)
            self.o0 = (lo + hi) / 2
            half = (hi - lo) / 2
            self.travel = math.sqrt(float(half @ half)) * (1 + 1e-12) + 1e-12
            self.o_lo, self.o_hi = lo, hi
            self.sideways = math.hypot(float(half[0]), float(half[1])) * (1 + 1e-12) + 1e-12
        self.cells = _Cells.of(rays.dirs)
        pr = np.asarray(rays.point_ray, np.int64)
        # the points grouped by ray: ray r's points are point_order[pstart[r]:pstart[r + 1]]
        self.point_order = np.arange(len(pr)) if np.all(pr[1:] >= pr[:-1]) \
            else np.argsort(pr, kind="stable")
        self.pstart = np.zeros(self.cells.n + 1, np.int64)
        np.cumsum(np.bincount(pr, minlength=self.cells.n), out=self.pstart[1:])

    def _spans(self, centre, reach):
        """The cone of rays toward a sphere of ``reach`` around ``centre`` as cell spans
        (``_cone_spans``), or None: every ray."""
        v = [float(centre[0] - self.o0[0]), float(centre[1] - self.o0[1]),
             float(centre[2] - self.o0[2])]
        dist = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if dist <= reach:
            return None
        return self._cone_spans(v, math.asin(min(1.0, reach / dist)))

    @staticmethod
    def _cone_spans(v, angle):
        """The directions within ``angle`` of ``v`` as cell spans: [(sector lo, sector
        hi, band lo, band hi)], or None where the cone holds a pole."""
        h = math.hypot(float(v[0]), float(v[1]))
        if h == 0.0:
            return None
        elevation = math.atan2(abs(float(v[2])), h)
        if angle >= math.pi / 2 - elevation:
            return None
        span = math.asin(min(1.0, math.sin(angle) / math.cos(elevation))) + PAD
        a = math.atan2(float(v[1]), float(v[0]))
        e = math.atan2(float(v[2]), h)
        b0, b1 = (_cell1(x, -math.pi / 2, EL_CELLS / math.pi, EL_CELLS)
                  for x in (e - angle - PAD, e + angle + PAD))
        lo, hi = a - span, a + span
        parts = [(lo, hi)]
        if lo < -math.pi:
            parts = [(-math.pi, hi), (lo + 2 * math.pi, math.pi)]
        elif hi > math.pi:
            parts = [(lo, math.pi), (-math.pi, hi - 2 * math.pi)]
        scale = AZ_CELLS / (2 * math.pi)
        return [(_cell1(p, -math.pi, scale, AZ_CELLS), _cell1(q, -math.pi, scale, AZ_CELLS),
                 b0, b1) for p, q in parts]

    def _bands(self, centre, extent):
        """For a box whose cone takes every ray (the origins near or in it): the span
        of elevation bands (``(lo, hi)``) that hold every ray that can reach its
        axis-aligned bounds ``centre`` +- ``extent`` when those lie wholly below or
        above every origin, else None. From origins below the box's top by at least
        g, no farther than H across from any of its points, a ray reaches it only at
        an elevation of at most atan2(-g, H) (the steepest, g the least drop and H the
        longest way across), and from above it at least atan2(g, H)."""
        pad = 1e-9 * (1.0 + float(np.abs(centre).max()) + float(np.abs(extent).max()))
        top = float(centre[2] + extent[2]) + pad
        bottom = float(centre[2] - extent[2]) - pad
        far = max(math.hypot(float(centre[0] + sx * extent[0] - self.o0[0]),
                             float(centre[1] + sy * extent[1] - self.o0[1]))
                  for sx in (-1, 1) for sy in (-1, 1)) + self.sideways + pad
        scale = EL_CELLS / math.pi
        if top < float(self.o_lo[2]):
            el = math.atan2(top - float(self.o_lo[2]), far)
            return 0, _cell1(el + PAD, -math.pi / 2, scale, EL_CELLS)
        if bottom > float(self.o_hi[2]):
            el = math.atan2(bottom - float(self.o_hi[2]), far)
            return _cell1(el - PAD, -math.pi / 2, scale, EL_CELLS), EL_CELLS - 1
        return None

    def segments(self, centres, radii, extents=None):
        """(box, lo, hi) arrays: for every box j (a sphere of ``radii[j]`` around
        ``centres[j]``), runs [lo, hi) of ``cells.order`` that hold a superset of the
        rays passing within that sphere, each ray once; runs no longer than
        ``SEGMENT`` (shares of work for the compiled counts). ``extents``: per box, the
        half sizes along the world axes of a box within the sphere (the ground-truth
        box grown by its margin), which narrows a sphere that holds the origins to the
        elevations that reach the box (``_bands``: a sensor on a car's roof)."""
        spans, owners = [], []  # every box's cell spans, then one pass over them all
        whole = []  # boxes that take every ray
        for j, (c, r) in enumerate(zip(centres, radii)):
            got = self._spans(c, float(r) + self.travel)
            bands = None if got is not None or extents is None \
                else self._bands(np.asarray(c, np.float64), np.asarray(extents[j], np.float64))
            if got is None and bands is None:
                whole.append(j)
                got = [(0, 0, 0, 0)]  # a placeholder: its run is every ray (below)
            elif got is None:
                got = [(0, AZ_CELLS - 1, *bands)]
            spans += got
            owners += [j] * len(got)
        if not owners:
            z = np.zeros(0, np.int64)
            return z, z, z
        lo, hi, box = _runs_of(self.cells.starts, np.array(spans, np.int64).reshape(-1, 4),
                               owners)
        if whole:  # one run [0, n) in place of each placeholder's
            every = np.isin(box, whole)
            lo[every], hi[every] = 0, self.cells.n
        keep = hi > lo
        box, lo, hi = box[keep], lo[keep], hi[keep]
        pieces = np.maximum((hi - lo + SEGMENT - 1) // SEGMENT, 1)
        if np.any(pieces > 1):  # long runs cut into pieces
            owner, k = _ranges(np.zeros(len(lo), np.int64), pieces)
            box, lo = box[owner], lo[owner] + k * SEGMENT
            hi = np.minimum(lo + SEGMENT, hi[owner])
        return box, lo, hi

    def pairs(self, segments):
        """(box, ray) of every ray in ``segments`` (``segments``' result)."""
        box, lo, hi = segments
        seg, pos = _ranges(lo, hi)
        return box[seg], self.cells.order[pos]

    def within(self, v, angle):
        """Sorted indices of a superset of the rays whose directions lie within
        ``angle`` of ``v``."""
        spans = self._cone_spans(np.asarray(v, np.float64), angle)
        if spans is None:
            return np.arange(self.cells.n)
        lo, hi, _ = _runs(self.cells.starts, spans, 0)
        return np.sort(self.cells.order[_ranges(lo, hi)[1]])

    def within_many(self, vs, angles):
        """(owner, ray) pairs: for every direction ``vs[j]``, a superset of the rays
        within ``angles[j]`` of it (``within``'s, each ray once, in no set order),
        all directions in one go."""
        spans, owners = [], []
        for j, (v, angle) in enumerate(zip(vs, angles)):
            got = self._cone_spans(np.asarray(v, np.float64), float(angle)) \
                or [(0, AZ_CELLS - 1, 0, EL_CELLS - 1)]
            spans += got
            owners += [j] * len(got)
        if not owners:
            z = np.zeros(0, np.int64)
            return z, z
        lo, hi, owner = _runs_of(self.cells.starts, np.array(spans, np.int64).reshape(-1, 4),
                                 owners)
        seg, pos = _ranges(lo, hi)
        return owner[seg], self.cells.order[pos]

    def points_of(self, box, ray):
        """(box, point) pairs of the points on the rays of (box, ray) pairs."""
        owner, pos = _ranges(self.pstart[ray], self.pstart[ray + 1])
        return box[owner], self.point_order[pos]
