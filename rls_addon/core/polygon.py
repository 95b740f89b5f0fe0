"""Simple polygons in the xy plane: validation, area, point-in-polygon, sampling.

A polygon is an (M, 2) float64 array of vertices in order (either winding);
the closing edge back to the first vertex is implied. Self-intersecting
outlines are not rejected: point-in-polygon follows the even-odd rule.
"""

import numpy as np

from .errors import RegionError

MIN_AREA_M2 = 1e-9


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
    area = abs(shoelace_area(poly))
    if area < MIN_AREA_M2:
        raise RegionError(f"region outline has zero area ({area:g} m^2): its vertices are collinear or repeated")
    return poly


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
