"""Lanes and junctions as 2-D pieces whose union is the surface.

A lane with a centre line and a width covers the union of, per segment, the rectangle
the segment sweeps at half the width either side, and at each bend, on its outer side,
the mitred wedge between two neighbouring rectangles (a bevel when the bend turns more
than ``MITER_LIMIT_DEG``). Where the polygon is simple this union is exactly the
polygon SUMO outlines a lane with: the centre line moved half the width to either side,
neighbouring segments' offsets meeting where they intersect (``PositionVector::
move2side`` in SUMO's utils/geom, ``sumolib.geomhelper.move2side`` in sumolib). Where
a lane bends tighter than half its width (SUMO's outline crosses itself there) the
union is still the area the lane sweeps: every piece is convex and counter-clockwise.

Outlines (junction shapes, walking areas) are pieces as they are when they do not cross
or touch themselves; one that does is flagged ``simple=False``, and the surface it
covers is the even-odd inside of its outline (a point is inside when a ray from it
crosses the outline an odd number of times), as the triangulation decides it.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import RegionError
from ..metrics.polygon import as_polygon, shoelace_area

MITER_LIMIT_DEG = 90.0
MIN_PIECE_AREA_M2 = 1e-6
_EPS = 1e-9


@dataclass(frozen=True)
class Piece:
    kind: str           # road, crossing, sidewalk
    ring: np.ndarray    # (n, 2), counter-clockwise when simple
    source: str         # the lane or junction id it comes from
    simple: bool = True


def _ccw(ring):
    a = shoelace_area(ring)
    if abs(a) < MIN_PIECE_AREA_M2:
        return None
    return ring if a > 0 else ring[::-1].copy()


def _dedupe(points):
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 2:
        return pts
    keep = np.r_[True, np.linalg.norm(np.diff(pts, axis=0), axis=1) > _EPS]
    return pts[keep]


def _areas(polys):
    """(k,) signed shoelace areas of (k, m, 2) polygons."""
    x, y = polys[..., 0], polys[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=1) - y * np.roll(x, -1, axis=1), axis=1)


def lane_pieces(shape, width):
    """Convex counter-clockwise (k, 2) polygons whose union is the lane's surface."""
    return lanes_pieces([shape], [width])[0]


def lanes_pieces(shapes, widths):
    """``lane_pieces`` of many lanes at once (one numpy pass over every segment and
    bend of all of them): per lane, its segments' rectangles, then its bends' wedges."""
    out = [[] for _ in shapes]
    if not len(shapes):
        return out
    pts = [_dedupe(sh) for sh in shapes]
    counts = np.array([len(p) for p in pts])
    h = 0.5 * np.asarray(widths, dtype=np.float64)
    P = np.concatenate([p for p in pts if len(p)]) if counts.sum() else np.zeros((0, 2))
    lane = np.repeat(np.arange(len(shapes)), counts)
    usable = (counts >= 2) & (h > 0)
    # segments: consecutive points of one usable lane
    seg = np.flatnonzero((lane[:-1] == lane[1:]) & usable[lane[:-1]])
    a, b, sl = P[seg], P[seg + 1], lane[seg]
    d = b - a
    d /= np.linalg.norm(d, axis=1)[:, None]
    n = np.c_[-d[:, 1], d[:, 0]] * h[sl][:, None]  # left normals, half a width long
    rects = np.stack([a - n, b - n, b + n, a + n], axis=1)  # counter-clockwise
    for i in np.flatnonzero(_areas(rects) >= MIN_PIECE_AREA_M2):
        out[sl[i]].append(rects[i])
    # bends: a segment and the next of the same lane
    j = np.flatnonzero(sl[:-1] == sl[1:]) if len(sl) > 1 else np.zeros(0, np.int64)
    d1, d2, n1, n2, p = d[j], d[j + 1], n[j], n[j + 1], b[j]
    turn = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    side = np.where(turn > 0, -1.0, 1.0)[:, None]  # the outer side: right of a left turn
    wa, wb = p + side * n1, p + side * n2
    m = n1 + n2
    mm = np.einsum("ij,ij->i", m, m)
    hj = h[sl[j]]
    tip = p + side * m * (2.0 * hj * hj / np.where(mm > 0, mm, 1.0))[:, None]
    mitre = np.einsum("ij,ij->i", d1, d2) >= np.cos(np.radians(MITER_LIMIT_DEG))
    for i in np.flatnonzero(np.abs(turn) >= 1e-12):
        wedge = (np.array([p[i], wa[i], tip[i], wb[i]]) if mitre[i]
                 else np.array([p[i], wa[i], wb[i]]))
        w = _ccw(wedge)
        if w is not None:
            out[sl[j[i]]].append(w)
    return out


def outline_piece(points, kind, source):
    """A ``Piece`` of the outline ``points`` (its repeated and closing vertices
    dropped), ``simple=False`` when it crosses or touches itself; None when it has
    fewer than three vertices or no area."""
    ring = _dedupe(points)
    if len(ring) > 1 and np.linalg.norm(ring[0] - ring[-1]) <= _EPS:
        ring = ring[:-1]
    if len(ring) < 3:
        return None
    try:
        as_polygon(ring)
    except RegionError:
        if abs(shoelace_area(ring)) < MIN_PIECE_AREA_M2 and _collinear(ring):
            return None
        return Piece(kind, ring, source, simple=False)
    r = _ccw(ring)
    return None if r is None else Piece(kind, r, source)


def _collinear(ring):
    d = ring - ring[0]
    return np.linalg.matrix_rank(d, tol=1e-9) < 2
