"""The road surface of a layout as triangles, tile by tile: which triangles, of which
kind, and the sidewalks' outline (for the kerbs).

The pieces of a whole network are triangulated in square tiles (``TILE_M``), not all at
once: a constrained Delaunay triangulation (CDT, handed in: Blender's
``mathutils.geometry.delaunay_2d_cdt`` through ``blender/roads.py``) of one tile's
square and the edges of the pieces that reach into it. Every piece's edges and the
tile's sides are edges of that triangulation, so each triangle lies wholly inside or
outside each piece and inside one tile; it is kept when its centroid lies inside the
tile and in a piece (the even-odd inside of its outline), with the kind that wins
there (``classify``). (The CDT's own record of which input faces hold a triangle was
tried: where many pieces share collinear edges, as lanes do, it marks triangles
outside every piece.) The tiles' triangles
together are the pieces' union, as one CDT of everything gave; a network of 30 x 30
junctions needed 2.9 GB and 150 s that way (issue #38), and each tile's CDT now holds only
its own pieces. Vertices the tiles share (on their sides) are merged, and the sides of
the tiles are left out of the sidewalks' outline (``kerb_edges``): kerbs stand only
where the sidewalk ends. The tile lines sit at an offset of ``TILE_OFFSET`` of a tile
from the pieces' lower-left corner, so that a piece's edge lies on one only by chance.
"""

import time

import numpy as np

from ..metrics.polygon import points_in_polygon
from .layout import KINDS

TILE_M = 160.0
TILE_OFFSET = 0.3819660112501051  # (3 - sqrt 5) / 2: no round fraction of a tile
MERGE_M = 1e-6     # vertices of neighbouring tiles this close are one
SEAM_M = 1e-6      # an outline edge this close to a tile line is a seam, not a kerb


def classify(points, pieces):
    """Per point (a triangle's centroid), the index in ``KINDS`` of the highest kind of
    piece it lies in (even-odd inside of the piece's outline), -1 for none. Pieces of
    three or four corners that are convex (lanes' rectangles and wedges) are tested all
    at once, on the sides' cross products; others one by one (``points_in_polygon``)."""
    rank = {kind: i for i, kind in enumerate(KINDS)}
    kind = np.full(len(points), -1, dtype=np.int64)
    if not len(points) or not pieces:
        return kind
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    quads = np.zeros((len(pieces), 4, 2))
    convex = np.zeros(len(pieces), dtype=bool)
    for k, p in enumerate(pieces):
        if p.simple and 3 <= len(p.ring) <= 4:
            quads[k, :len(p.ring)] = p.ring
            quads[k, len(p.ring):] = p.ring[-1]  # a triangle: its last corner twice
            convex[k] = True
    e = np.roll(quads, -1, axis=1) - quads
    turns = e[:, :, 0] * np.roll(e, -1, axis=1)[:, :, 1] - e[:, :, 1] * np.roll(e, -1, axis=1)[:, :, 0]
    convex &= (turns >= 0).all(axis=1)
    pair_pt, pair_pc = [], []
    for k, p in enumerate(pieces):
        lo, hi = p.ring.min(axis=0), p.ring.max(axis=0)
        cand = order[np.searchsorted(xs, lo[0]):np.searchsorted(xs, hi[0], side="right")]
        cand = cand[(points[cand, 1] >= lo[1]) & (points[cand, 1] <= hi[1])]
        if not len(cand):
            continue
        if convex[k]:
            pair_pt.append(cand)
            pair_pc.append(np.full(len(cand), k))
            continue
        inside = cand[points_in_polygon(points[cand], p.ring)]
        kind[inside] = np.maximum(kind[inside], rank[p.kind])
    if pair_pt:
        pt, pc = np.concatenate(pair_pt), np.concatenate(pair_pc)
        d = points[pt][:, None, :] - quads[pc]
        eq = e[pc]
        inside = ((eq[:, :, 0] * d[:, :, 1] - eq[:, :, 1] * d[:, :, 0]) >= 0).all(axis=1)
        ranks = np.array([rank[p.kind] for p in pieces])
        np.maximum.at(kind, pt[inside], ranks[pc[inside]])
    return kind


def boundary_edges(tris):
    """Directed edges (a, b) of the counter-clockwise triangles ``tris`` that no other
    of them shares: the region's outline, inside on the left."""
    if not len(tris):
        return np.zeros((0, 2), np.int64)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[counts[inv.ravel()] == 1]


class Tiling:
    """The square tiles over ``pieces``: tile (i, j) is [x0 + i s, x0 + (i + 1) s] x
    [y0 + j s, y0 + (j + 1) s]."""

    def __init__(self, pieces, size=TILE_M):
        self.size = float(size)
        lo = np.array([p.ring.min(axis=0) for p in pieces]).reshape(-1, 2)
        hi = np.array([p.ring.max(axis=0) for p in pieces]).reshape(-1, 2)
        self.lo, self.hi = lo, hi
        start = lo.min(axis=0) - TILE_OFFSET * self.size if len(lo) else np.zeros(2)
        self.origin = start
        top = hi.max(axis=0) if len(hi) else np.ones(2)
        self.shape = tuple(int(v) for v in np.floor((top - start) / self.size) + 1)

    def members(self):
        """{(i, j): [piece indices]} of the tiles any piece reaches into."""
        i0 = np.floor((self.lo - self.origin) / self.size).astype(np.int64)
        i1 = np.floor((self.hi - self.origin) / self.size).astype(np.int64)
        out = {}
        for k in range(len(i0)):
            for i in range(i0[k, 0], i1[k, 0] + 1):
                for j in range(i0[k, 1], i1[k, 1] + 1):
                    out.setdefault((i, j), []).append(k)
        return out

    def box(self, i, j):
        x0, y0 = self.origin + self.size * np.array([i, j], dtype=np.float64)
        return x0, x0 + self.size, y0, y0 + self.size

    def on_seam(self, a, b):
        """Per edge (a, b): whether it lies along a tile line."""
        out = np.zeros(len(a), dtype=bool)
        for axis in (0, 1):
            fa = (a[:, axis] - self.origin[axis]) / self.size
            fb = (b[:, axis] - self.origin[axis]) / self.size
            ka = np.round(fa)
            out |= ((np.abs(fa - ka) * self.size <= SEAM_M)
                    & (np.abs(fb - ka) * self.size <= SEAM_M))
        return out


def triangulate(pieces, cdt, progress=None, size=TILE_M):
    """(V, 2) float64 vertices, (T, 3) counter-clockwise triangles, (T,) kind index
    (into ``KINDS``) of the union of ``pieces``, and the ``Tiling`` used.

    ``cdt(points (n, 2), edges (m, 2), centre (2,)) -> (vertices (V, 2), triangles
    (T, 3))``: a constrained Delaunay triangulation of the points and edges (edges split
    where they cross), worked out relative to ``centre``. ``progress(done, total,
    seconds_left)`` after each tile."""
    if not pieces:
        return (np.zeros((0, 2)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64),
                Tiling([], size))
    tiling = Tiling(pieces, size)
    members = tiling.members()
    allpts = np.concatenate([tiling.lo, tiling.hi])
    centre = 0.5 * (allpts.min(axis=0) + allpts.max(axis=0))  # one for every tile
    verts, tris, kinds, base = [], [], [], 0
    t0 = time.perf_counter()
    for done, ((i, j), ks) in enumerate(sorted(members.items()), start=1):
        v, t, kind = _tile(tiling.box(i, j), [pieces[k] for k in ks], cdt, centre)
        if len(t):
            used, inv = np.unique(t.ravel(), return_inverse=True)
            verts.append(v[used])
            tris.append(inv.reshape(t.shape) + base)
            kinds.append(kind)
            base += len(used)
        if progress is not None:
            spent = time.perf_counter() - t0
            progress(done, len(members), spent / done * (len(members) - done))
    if not tris:
        return (np.zeros((0, 2)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), tiling)
    v = np.concatenate(verts)
    t = np.concatenate(tris)
    kind = np.concatenate(kinds)
    key = np.round((v - centre) / MERGE_M).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    v, t = v[first], inv.ravel()[t]
    a, b, c = (v[t[:, k]] for k in range(3))
    cw = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    t[cw] = t[cw][:, ::-1]
    return v, t, kind, tiling


def _tile(box, tile, cdt, centre):
    """One tile's (vertices, triangles, kind) (see ``triangulate``)."""
    x0, x1, y0, y1 = box
    rings = [np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])] + [p.ring for p in tile]
    starts = np.cumsum([0] + [len(r) for r in rings[:-1]])
    pts = np.concatenate(rings)
    edges = np.concatenate([np.c_[s + np.arange(len(r)), s + (np.arange(len(r)) + 1) % len(r)]
                            for s, r in zip(starts, rings)])
    v, t = cdt(pts, edges, centre)
    if not len(t):
        return v, t, np.zeros(0, np.int64)
    c = v[t].mean(axis=1)
    t = t[(c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)]
    kind = classify(v[t].mean(axis=1), tile)
    keep = kind >= 0
    return v, t[keep], kind[keep]


def kerb_edges(v, tris, kind, tiling, min_length):
    """Directed edges (a, b) of the sidewalk surface's outline (sidewalk on the left),
    without the tiles' seams and edges shorter than ``min_length``."""
    walk = tris[kind == KINDS.index("sidewalk")]
    edges = boundary_edges(walk)
    if not len(edges):
        return edges
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    keep = (np.linalg.norm(b - a, axis=1) >= min_length) & ~tiling.on_seam(a, b)
    return edges[keep]
