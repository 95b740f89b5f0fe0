"""The plan of a scene built from a SUMO network: its surface pieces by kind, the
junction the scene is about, the mounts at that junction's corners and its InfraLOB.

Conventions (docs/roads.md):

* kinds of surface, and which wins where pieces overlap: ``sidewalk`` (sidewalk lanes,
  walking areas; raised by ``KERB_M``) over ``crossing`` (pedestrian crossings, at
  road level) over ``road`` (lanes, internal lanes, junction shapes);
* the scene's origin (``ORIGINS``): ``net`` puts the scene's (0, 0) at the network's
  (0, 0), so scene x, y = SUMO's x, y (already shifted by the network's netOffset);
  ``junction`` puts it at the chosen junction's position, so scene x, y = SUMO's x, y
  minus that position. Either way ``RoadLayout.origin`` is the network coordinates of
  the scene's (0, 0): scene = net - origin, for lanes and for SUMO's traffic alike;
* the junction: the one named, else the largest by the area of its outline (ties: the
  first in the network's order); internal nodes are not junctions;
* the InfraLOB: the junction outline's bounding box grown by ``REGION_MARGIN_M``;
* the mounts: one per gap between the roads that meet at the junction (roads within
  ``SAME_ROAD_DEG`` of each other are one), on the gap's bisector from the junction's
  centre, ``POLE_CLEARANCE_M`` beyond the last road or crossing surface; on a sidewalk
  when the network has one there.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..metrics.polygon import points_in_polygon, shoelace_area
from .pieces import Piece, lane_pieces, outline_piece

KINDS = ("road", "crossing", "sidewalk")  # lowest priority first
KERB_M = 0.15            # as the sample scenes' kerbs (blender/scenes/streets.py)
REGION_MARGIN_M = 5.0
SAME_ROAD_DEG = 20.0
MIN_GAP_DEG = 30.0
POLE_CLEARANCE_M = 1.0
POLE_STEP_M = 0.25
POLE_SEARCH_M = 80.0
ORIGINS = ("net", "junction")
LIST_IDS = 8


@dataclass
class Mount:
    name: str
    xy: np.ndarray
    on_sidewalk: bool


@dataclass
class RoadLayout:
    pieces: list          # Piece, coordinates in the scene's frame
    junction: object      # network.Junction (net coordinates)
    origin: np.ndarray    # net coordinates of the scene's (0, 0)
    region: tuple         # (x0, x1, y0, y1) in the scene's frame
    mounts: list          # Mount, scene frame
    net_offset: tuple

    def count(self, kind):
        return sum(p.kind == kind for p in self.pieces)


def choose_junction(net, junction_id=None):
    if not net.junctions:
        raise InputError(f"{net.path} has no junctions (only internal nodes or none): "
                         "there is nothing to put an InfraLOB over")
    if junction_id is not None:
        j = net.junction(junction_id)
        if j is None:
            ids = [k.id for k in sorted(net.junctions, key=lambda k: -_area(k.shape))]
            more = f", ... ({len(ids)} in all)" if len(ids) > LIST_IDS else ""
            raise InputError(f"no junction {junction_id!r} in {net.path}; junctions there "
                             f"(largest first): {', '.join(ids[:LIST_IDS])}{more}")
        return j
    best = max(net.junctions, key=lambda k: _area(k.shape))  # first of the largest
    return best


def _area(shape):
    return abs(shoelace_area(shape)) if len(shape) >= 3 else 0.0


def surface_pieces(net, origin=(0.0, 0.0)):
    """Every lane's and junction's pieces, shifted by ``-origin``."""
    o = np.asarray(origin, dtype=np.float64)
    pieces = []
    for j in net.junctions:
        p = outline_piece(j.shape - o if len(j.shape) else j.shape, "road", j.id)
        if p is not None:
            pieces.append(p)
    for lane in net.lanes:
        shape = lane.shape - o
        if lane.kind == "walkingarea":
            p = outline_piece(shape, "sidewalk", lane.id)
            if p is not None:
                pieces.append(p)
            continue
        kind = "sidewalk" if lane.kind == "sidewalk" else lane.kind
        pieces += [Piece(kind, r, lane.id) for r in lane_pieces(shape, lane.width)]
    return pieces


def build_layout(net, junction_id=None, origin="net"):
    if origin not in ORIGINS:
        raise InputError(f"--origin must be one of {', '.join(ORIGINS)}, got {origin!r}")
    j = choose_junction(net, junction_id)
    if not net.lanes:
        raise InputError(f"{net.path} has no lanes: there are no roads to build")
    o = j.centre.copy() if origin == "junction" else np.zeros(2)
    pieces = surface_pieces(net, o)
    shape = (j.shape if len(j.shape) >= 3 else j.centre[None, :]) - o
    lo, hi = shape.min(axis=0) - REGION_MARGIN_M, shape.max(axis=0) + REGION_MARGIN_M
    region = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
    mounts = corner_mounts(j, pieces, j.centre - o)
    return RoadLayout(pieces=pieces, junction=j, origin=o, region=region, mounts=mounts,
                      net_offset=net.net_offset)


def _inside(points, pieces):
    pts = np.atleast_2d(points)
    hit = np.zeros(len(pts), dtype=bool)
    for p in pieces:
        hit |= points_in_polygon(pts, p.ring)
    return hit


def road_gaps(directions):
    """Bisector angles (radians) of the gaps of at least ``MIN_GAP_DEG`` between the
    road directions (unit vectors), roads within ``SAME_ROAD_DEG`` merged; a junction
    with one road (a dead end) has one gap, opposite it."""
    if not len(directions):
        return [0.0, np.pi / 2, np.pi, 1.5 * np.pi]
    ang = np.sort(np.mod([np.arctan2(d[1], d[0]) for d in directions], 2 * np.pi))
    groups = [[ang[0]]]
    for a in ang[1:]:
        if a - groups[-1][-1] > np.radians(SAME_ROAD_DEG):
            groups.append([a])
        else:
            groups[-1].append(a)
    if len(groups) > 1 and groups[0][0] + 2 * np.pi - groups[-1][-1] <= np.radians(SAME_ROAD_DEG):
        groups[0] = [a - 2 * np.pi for a in groups.pop()] + groups[0]
    merged = [float(np.mod(np.mean(g), 2 * np.pi)) for g in groups]  # a road's two ways
    merged.sort()
    merged = np.array(merged)
    nxt = np.r_[merged[1:], merged[0] + 2 * np.pi]
    gaps = nxt - merged
    return [float(np.mod(a + g / 2, 2 * np.pi))
            for a, g in zip(merged, gaps) if g >= np.radians(MIN_GAP_DEG)]


COMPASS = ("E", "NE", "N", "NW", "W", "SW", "S", "SE")


def corner_mounts(junction, pieces, centre):
    """A mount per corner of the junction (see the module's conventions)."""
    near = [p for p in pieces if np.min(np.linalg.norm(p.ring - centre, axis=1)) < POLE_SEARCH_M
            or points_in_polygon(centre[None, :], p.ring)[0]]
    paved = [p for p in near if p.kind in ("road", "crossing")]
    walks = [p for p in near if p.kind == "sidewalk"]
    ts = np.arange(0.0, POLE_SEARCH_M, POLE_STEP_M)
    mounts = []
    for k, a in enumerate(road_gaps(junction.roads)):
        u = np.array([np.cos(a), np.sin(a)])
        ray = centre + ts[:, None] * u
        off = ~_inside(ray, paved) | _inside(ray, walks)  # sidewalks win
        span = int(np.ceil(2 * POLE_CLEARANCE_M / POLE_STEP_M)) + 1
        clear = np.array([off[i:i + span].all() for i in range(len(ts) - span)])
        first = np.flatnonzero(clear)
        t = (ts[first[0]] if len(first) else ts[-1]) + POLE_CLEARANCE_M
        xy = centre + t * u
        compass = COMPASS[int(np.round(a / (np.pi / 4))) % 8]
        mounts.append(Mount(name=f"Pole {compass} {junction.id}", xy=xy,
                            on_sidewalk=bool(_inside(xy, walks)[0])))
    base = [m.name for m in mounts]
    for i, m in enumerate(mounts):
        if base.count(base[i]) > 1:
            m.name = f"{base[i]} {base[:i + 1].count(base[i])}"
    return mounts


def network_layout(path, junction_id=None, origin="net"):
    """(network, ``RoadLayout``) of the SUMO network file ``path``: what ``rls scene
    from-net`` and *File > Import > SUMO Network as Scene* build a scene from."""
    from .network import read_network

    net = read_network(path)
    return net, build_layout(net, junction_id, origin)
