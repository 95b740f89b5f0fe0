"""Simple polygons in the xy plane: validation, area, point-in-polygon, sampling.

A polygon is an (M, 2) float64 array of vertices in order (either winding);
the closing edge back to the first vertex is implied. An outline that crosses or
touches itself is refused (``as_polygon``): its net (shoelace) area and the area its
even-odd inside covers differ, so no density over it would be right.
"""

from fractions import Fraction

import numpy as np

from ..errors import RegionError

MIN_AREA_M2 = 1e-9
# Shewchuk's bound on the rounding of a float orientation (a - c) x (b - c): a sign
# beyond it is certain; within it the orientation is worked out in exact rationals.
_ORIENT_BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53
_PAIRS_PER_CHUNK = 1 << 21


def shoelace_area(poly):
    """Signed area (positive for counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def as_polygon(vertices):
    """Validated (M, 2) float64 polygon; ``RegionError`` if degenerate."""
    try:
        poly = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise RegionError("region outline must be a list of [x, y] vertices") from None
    if poly.ndim != 2 or poly.shape[1] != 2:
        raise RegionError(f"region outline must be an (M, 2) array of xy vertices, got shape {poly.shape}")
    if not np.isfinite(poly).all():
        raise RegionError("region outline has non-finite coordinates")
    if len(poly) > 1 and np.array_equal(poly[0], poly[-1]):
        poly = poly[:-1]  # explicitly closed ring
    if len(poly) < 3:
        raise RegionError(f"region outline needs at least 3 vertices, got {len(poly)}")
    _refuse_crossing(poly)
    area = abs(shoelace_area(poly))
    if area < MIN_AREA_M2:
        raise RegionError(f"region outline has zero area ({area:g} m^2): its vertices are collinear or repeated")
    return poly


def _orientation(a, b, c):
    """Exact sign (-1, 0, 1) of the orientation (a - c) x (b - c) of rows of points:
    counter-clockwise positive. Float arithmetic where its error bound decides the
    sign, exact rationals for the rest (points on one line, or nearly)."""
    left = (a[:, 0] - c[:, 0]) * (b[:, 1] - c[:, 1])
    right = (a[:, 1] - c[:, 1]) * (b[:, 0] - c[:, 0])
    det = left - right
    sign = np.sign(det).astype(np.int8)
    for k in np.flatnonzero(np.abs(det) <= _ORIENT_BOUND * (np.abs(left) + np.abs(right))):
        (ax, ay), (bx, by), (cx, cy) = ([Fraction(float(v)) for v in p[k]] for p in (a, b, c))
        exact = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)
        sign[k] = (exact > 0) - (exact < 0)
    return sign


def _within(a, b, p):
    """Whether points p, on the lines through a and b, lie on the segments a-b."""
    return ((np.minimum(a[:, 0], b[:, 0]) <= p[:, 0]) & (p[:, 0] <= np.maximum(a[:, 0], b[:, 0]))
            & (np.minimum(a[:, 1], b[:, 1]) <= p[:, 1]) & (p[:, 1] <= np.maximum(a[:, 1], b[:, 1])))


def _refuse_crossing(poly):
    """``RegionError`` naming where the closed outline ``poly`` crosses or touches
    itself (two edges that are not neighbours meet, or an edge runs back along its
    neighbour), unless all its vertices lie on one line (``as_polygon`` says so then).
    Exact: orientations by ``_orientation``, the rest comparisons. Repeated vertices
    in a row are one vertex here (the last of them names it)."""
    keep = np.r_[np.any(poly[1:] != poly[:-1], axis=1), True]  # the last of a run
    ring = poly[keep]
    at = np.flatnonzero(keep)  # the vertex numbers of the ring's vertices
    if len(ring) > 1 and np.array_equal(ring[0], ring[-1]):
        ring, at = ring[:-1], at[:-1]
    m = len(ring)
    if m < 3:
        return
    a, b = ring, np.roll(ring, -1, axis=0)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    found = []
    # Neighbours meet at their shared vertex; they cross only by running back along
    # each other: on one line, pointing apart.
    c = np.roll(ring, -2, axis=0)
    back = np.flatnonzero(_orientation(a, b, c) == 0)
    for i in back:
        u, v = ring[(i + 1) % m] - ring[i], ring[(i + 2) % m] - ring[(i + 1) % m]
        if Fraction(float(u[0])) * Fraction(float(v[0])) + \
                Fraction(float(u[1])) * Fraction(float(v[1])) < 0:
            found.append((min(i, (i + 1) % m), max(i, (i + 1) % m), ring[(i + 1) % m]))
            break
    if back.size and len(back) == m:
        return  # every vertex on one line: no area (as_polygon's message)
    # Edges that are not neighbours and whose boxes overlap: with the edges sorted by
    # their least x, each pair once, as (the one that starts first, one that starts
    # within its x span); a chunk of pairs at a time.
    order = np.argsort(lo[:, 0], kind="stable")
    first_x = lo[order, 0]
    count = np.searchsorted(first_x, hi[order, 0], side="right") - np.arange(m) - 1
    count = np.maximum(count, 0)
    ends = np.cumsum(count)
    s0 = 0
    while s0 < m:
        s1 = max(s0 + 1, int(np.searchsorted(ends, (ends[s0 - 1] if s0 else 0)
                                             + _PAIRS_PER_CHUNK, side="right")))
        s1 = min(s1, m)
        n = count[s0:s1]
        pos = np.repeat(np.arange(s0, s1), n)
        offset = np.arange(len(pos)) - np.repeat(np.cumsum(n) - n, n)
        s0 = s1
        e1, e2 = order[pos], order[pos + 1 + offset]
        ii, jj = np.minimum(e1, e2), np.maximum(e1, e2)
        ok = (jj - ii >= 2) & ~((ii == 0) & (jj == m - 1)) \
            & (lo[ii, 1] <= hi[jj, 1]) & (lo[jj, 1] <= hi[ii, 1])
        ii, jj = ii[ok], jj[ok]
        if not len(ii):
            continue
        p, q, r, t = a[ii], b[ii], a[jj], b[jj]
        o1, o2 = _orientation(p, q, r), _orientation(p, q, t)
        o3, o4 = _orientation(r, t, p), _orientation(r, t, q)
        on = [(o1 == 0) & _within(p, q, r), (o2 == 0) & _within(p, q, t),
              (o3 == 0) & _within(r, t, p), (o4 == 0) & _within(r, t, q)]
        hit = ((o1 * o2 < 0) & (o3 * o4 < 0)) | on[0] | on[1] | on[2] | on[3]
        k = np.flatnonzero(hit)
        if len(k):
            k = k[np.lexsort((jj[k], ii[k]))[0]]  # the first pair: lowest edges
            touch = [w for w, o in zip((r, t, p, q), on) if o[k]]
            found.append((int(ii[k]), int(jj[k]),
                          touch[0][k] if touch else _meet(p[k], q[k], r[k], t[k])))
    if not found:
        return
    i, j, (x, y) = min(found, key=lambda f: (f[0], f[1]))

    def edge(e):
        return f"edge {at[e] + 1} (vertex {at[e] + 1} to {at[(e + 1) % m] + 1})"

    raise RegionError(f"the region's outline crosses itself at ({x:g}, {y:g}): {edge(i)} "
                      f"meets {edge(j)}; draw it as one loop that does not cross or touch "
                      "itself")


def _meet(p, q, r, t):
    """Where the segments p-q and r-t, which cross, meet."""
    d1, d2 = q - p, t - r
    s = ((r[0] - p[0]) * d2[1] - (r[1] - p[1]) * d2[0]) / (d1[0] * d2[1] - d1[1] * d2[0])
    return p + s * d1


def polygon_centroid(vertices):
    """(x, y) of the region's centre: the centroid of its area, which a mean of its
    vertices is not when they are unevenly spaced (a rounded corner drawn with many
    vertices pulls that mean into the corner), nor with a vertex repeated. Worked out
    about the vertices' mean, and that mean itself where the two agree to rounding (a
    rectangle, any outline symmetric about it), so those stay exactly as they were."""
    poly = as_polygon(vertices)
    keep = np.r_[np.any(poly[1:] != poly[:-1], axis=1), np.any(poly[-1] != poly[0])]
    ring = poly[keep] if keep.any() else poly
    m = ring.mean(axis=0)
    p = ring - m
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    area = 0.5 * float(cross.sum())
    c = np.array([float(((x + x1) * cross).sum()), float(((y + y1) * cross).sum())]) / (6.0 * area)
    scale = max(1.0, float(np.abs(p).max()))
    return m if float(np.abs(c).max()) <= 1e-9 * scale else m + c


def polygon_area(vertices):
    """Area in square metres (absolute shoelace)."""
    return abs(shoelace_area(as_polygon(vertices)))


def points_in_polygon(xy, poly):
    """Boolean mask of the (N, 2) points inside ``poly`` (even-odd rule).

    Vectorised over points, one pass per edge. Points exactly on an edge may
    fall either way.
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    px, py = xy[:, 0], xy[:, 1]
    inside = np.zeros(len(xy), dtype=bool)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    box = (px >= lo[0]) & (px <= hi[0]) & (py >= lo[1]) & (py <= hi[1])
    idx = np.flatnonzero(box)
    bx, by = px[idx], py[idx]
    hit = np.zeros(len(idx), dtype=bool)
    x1, y1 = poly[:, 0], poly[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    for a, b, c, d in zip(x1, y1, x2, y2):
        if b == d:
            continue  # horizontal edges never cross a horizontal ray
        crosses = (b > by) != (d > by)
        xint = a + (by - b) * (c - a) / (d - b)
        hit ^= crosses & (bx < xint)
    inside[idx] = hit
    return inside


def grid_cells(x, y, lo, size, nx, ny):
    """(N,) int64 row-major cell of each point (``x``, ``y``) on a grid of ``nx`` x ``ny``
    square cells of ``size`` from corner ``lo``. Points beyond the grid, or not finite,
    are put in its outer ring of cells (the nearest border cell; a NaN coordinate in the
    first), which the callers keep free of anything to find."""
    fx = (x - lo[0]) / size
    fy = (y - lo[1]) / size
    if len(fx) and not (fx.min() >= 0 and fy.min() >= 0 and fx.max() < nx and fy.max() < ny):
        fx = np.where(fx >= 0, np.minimum(fx, nx - 1), 0.0)
        fy = np.where(fy >= 0, np.minimum(fy, ny - 1), 0.0)
    cell = fy.astype(np.int64)
    cell *= nx
    cell += fx.astype(np.int64)
    return cell


class PreparedPolygon:
    """``points_in_polygon`` for one outline and many point sets (a study's candidates):
    a grid over the outline's box, one ring of cells wider, whose cells are sorted once
    into wholly inside, wholly outside (the cell's centre is farther from every edge
    than its half-diagonal, with a margin for rounding) and crossed by the outline. A
    point in a decided cell takes the cell's answer; the points of the crossed cells
    are tested by ``points_in_polygon`` itself. The same answers, point for point: away
    from the edges by more than the margin, ``points_in_polygon``'s rounding cannot
    change its answer (tests/core/test_metrics.py)."""

    def __init__(self, poly, cells=128):
        self.poly = poly
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        self.size = size = float((hi - lo).max()) / cells
        self.lo = lo - size                                  # the ring of cells around
        self.nx, self.ny = (int(v) + 2 for v in np.ceil((hi - lo) / size))
        ix, iy = np.meshgrid(np.arange(self.nx), np.arange(self.ny))
        centres = self.lo + size * (np.stack([ix.ravel(), iy.ravel()], axis=1) + 0.5)
        slack = 1e-9 * max(1.0, size, float(np.abs(lo).max()), float(np.abs(hi).max()))
        decided = distance_to_boundary(centres, poly) > size * 0.5 * np.sqrt(2.0) + slack
        # 0 outside, 1 inside, 2 crossed by the outline: test the points
        self.state = np.where(decided, points_in_polygon(centres, poly), 2).astype(np.int8)
        x1, y1 = poly[:, 0], poly[:, 1]
        x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
        slanted = y1 != y2  # as points_in_polygon: horizontal edges never cross the ray
        self.box = lo, hi
        self.edges = x1[slanted], y1[slanted], x2[slanted], y2[slanted]

    def contains(self, xy):
        """``points_in_polygon(xy, poly)``."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        # beyond the grid (or not finite): into the ring, outside the outline's box
        cell = grid_cells(xy[:, 0], xy[:, 1], self.lo, self.size, self.nx, self.ny)
        state = self.state.take(cell)
        inside = state == 1
        test = np.flatnonzero(state == 2)
        inside[test] = self._exact(xy.take(test, axis=0))
        return inside

    def _exact(self, xy):
        """``points_in_polygon`` of a few points, every edge at once: its comparisons
        and its arithmetic, element for element (its loop over the edges costs more than
        the tests of the points of the crossed cells)."""
        if len(xy) * len(self.edges[0]) > 1_000_000:
            return points_in_polygon(xy, self.poly)
        (lo, hi), (a, b, c, d) = self.box, self.edges
        bx, by = xy[:, :1], xy[:, 1:]
        box = (bx[:, 0] >= lo[0]) & (bx[:, 0] <= hi[0]) & (by[:, 0] >= lo[1]) \
            & (by[:, 0] <= hi[1])
        crosses = (b > by) != (d > by)
        with np.errstate(invalid="ignore", over="ignore"):  # points not finite: off the box
            xint = a + (by - b) * (c - a) / (d - b)
        return box & (np.count_nonzero(crosses & (bx < xint), axis=1) % 2 == 1)


def distance_to_boundary(xy, poly):
    """Distance from each (N, 2) point to the nearest polygon edge."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    best = np.full(len(xy), np.inf)
    a = poly
    b = np.roll(poly, -1, axis=0)
    for p0, p1 in zip(a, b):
        seg = p1 - p0
        L2 = float(seg @ seg)
        t = np.zeros(len(xy)) if L2 == 0 else np.clip(((xy - p0) @ seg) / L2, 0.0, 1.0)
        proj = p0 + t[:, None] * seg
        np.minimum(best, np.hypot(*(xy - proj).T), out=best)
    return best


# Widening of the arc ``polygon_arc`` gives (radians): rays within float noise of its
# edge are kept, never dropped.
ARC_MARGIN_RAD = 1e-3


def polygon_arc(poly, origin, margin_rad=ARC_MARGIN_RAD):
    """The directions (azimuths) in which the polygon lies as seen from ``origin`` (xy):
    (start, extent) in radians, counter-clockwise, widened by ``margin_rad`` on each
    side; None when it lies in every direction (``origin`` inside the polygon, on its
    outline, or the outline winds around it). Walking the outline, the direction to
    the walker turns continuously (an edge that does not pass through the origin turns
    it by less than half a turn, one way), so the directions met form one arc: from the
    least to the greatest of that turning angle at the vertices."""
    poly = np.asarray(poly, np.float64)
    o = np.asarray(origin, np.float64).reshape(2)
    v = poly - o
    if points_in_polygon(o[None], poly)[0] or distance_to_boundary(o[None], poly)[0] <= 1e-9:
        return None
    theta = np.arctan2(v[:, 1], v[:, 0])
    step = np.diff(np.append(theta, theta[0]))
    step = (step + np.pi) % (2.0 * np.pi) - np.pi   # each edge's turn, in (-pi, pi]
    walk = theta[0] + np.concatenate([[0.0], np.cumsum(step[:-1])])
    lo, hi = float(walk.min()) - margin_rad, float(walk.max()) + margin_rad
    if hi - lo >= 2.0 * np.pi:
        return None
    return lo, hi - lo


def in_arc(arc, directions):
    """Indices of the ``directions`` ((N, 3) or (N, 2); only x and y are read) whose
    azimuth lies in ``arc`` ((start, extent) as ``polygon_arc`` gives it; a direction
    with no horizontal part is kept); None when ``arc`` is None (every direction).
    With ``polygon_arc(poly, origin)``: the directions whose half-line from ``origin``
    may cross the polygon (a point along a ray lies on its half-line, so the others
    cannot put a point inside). Sign tests of cross products, no angle per
    direction."""
    if arc is None:
        return None
    start, extent = arc
    d = np.asarray(directions, np.float64)
    x, y = d[:, 0], d[:, 1]
    s = np.array([np.cos(start), np.sin(start)])
    e = np.array([np.cos(start + extent), np.sin(start + extent)])
    after_start = s[0] * y - s[1] * x    # cross(s, u): u counter-clockwise of s
    before_end = x * e[1] - y * e[0]     # cross(u, e): u clockwise of e
    if extent <= np.pi:
        inside = (after_start >= 0) & (before_end >= 0)
    else:  # not in the gap from e round to s (less than half a turn)
        inside = ~((after_start < 0) & (before_end < 0))
    return np.flatnonzero(inside)


def sample_in_polygon(poly, count, rng, margin=0.0, max_rounds=1000):
    """``count`` points uniform in ``poly`` by rejection sampling from its bounding box.

    With ``margin`` > 0 only points at least that far from every edge are kept
    (so a disk of that radius lies wholly inside). Deterministic for a seeded
    ``numpy.random.Generator``.
    """
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    out, have = [], 0
    box_area = float(np.prod(hi - lo))
    frac = max(abs(shoelace_area(poly)) / box_area, 1e-6)
    for _ in range(max_rounds):
        if have >= count:
            break
        batch = int(min(max((count - have) / frac * 1.3 + 64, 256), 4_000_000))
        cand = rng.uniform(lo, hi, size=(batch, 2))
        keep = points_in_polygon(cand, poly)
        if margin > 0:
            keep[keep] = distance_to_boundary(cand[keep], poly) >= margin
        cand = cand[keep]
        out.append(cand)
        have += len(cand)
    if have < count:
        what = f"a disk of radius {margin:g} m" if margin > 0 else "a sample point"
        raise RegionError(f"region is too small or thin to place {what} inside it; use a smaller radius")
    return np.concatenate(out)[:count] if out else np.empty((0, 2))
