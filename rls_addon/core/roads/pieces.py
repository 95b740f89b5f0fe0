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


def lane_pieces(shape, width):
    """Convex counter-clockwise (k, 2) polygons whose union is the lane's surface."""
    pts = _dedupe(shape)
    h = 0.5 * float(width)
    if len(pts) < 2 or h <= 0:
        return []
    d = np.diff(pts, axis=0)
    d /= np.linalg.norm(d, axis=1)[:, None]
    n = np.c_[-d[:, 1], d[:, 0]]  # left normals
    out = []
    for i in range(len(d)):
        a, b = pts[i], pts[i + 1]
        rect = np.array([a - n[i] * h, b - n[i] * h, b + n[i] * h, a + n[i] * h])
        r = _ccw(rect)
        if r is not None:
            out.append(r)
    cos_limit = np.cos(np.radians(MITER_LIMIT_DEG))
    for i in range(1, len(pts) - 1):
        d1, d2, n1, n2, p = d[i - 1], d[i], n[i - 1], n[i], pts[i]
        turn = d1[0] * d2[1] - d1[1] * d2[0]
        if abs(turn) < 1e-12:
            continue
        side = -1.0 if turn > 0 else 1.0  # the outer side: right of a left turn
        a, b = p + side * n1 * h, p + side * n2 * h
        if float(np.dot(d1, d2)) >= cos_limit:
            m = n1 + n2
            tip = p + side * m * (2.0 * h / float(np.dot(m, m)))
            wedge = np.array([p, a, tip, b])
        else:
            wedge = np.array([p, a, b])
        w = _ccw(wedge)
        if w is not None:
            out.append(w)
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
