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
* the junction: the one named, else the signalised one (a SUMO node type
  ``traffic_light*``) with the most incoming lanes (of edges ending there, sidewalks
  left out), then the largest by the area of its outline (ties: the first in the
  network's order); without a signalised junction, the one with the most incoming
  lanes. Internal nodes are not junctions;
* the InfraLOB: the junction outline's bounding box grown by ``REGION_MARGIN_M``;
* the mounts: one per gap between the roads that meet at the junction (roads within
  ``SAME_ROAD_DEG`` of each other are one), on the gap's bisector from the junction's
  centre, ``POLE_CLEARANCE_M`` beyond the last road or crossing surface; on a sidewalk
  when the network has one there. A pole stands at most ``MOUNT_REACH_M`` outside the
  InfraLOB: where the bisector finds no clear ground that near (it runs along a road
  whose two ways diverge, say), that gap gets no pole and a notice says so.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..metrics.polygon import points_in_polygon, shoelace_area
from ..scene.extent import check_span
from .pieces import Piece, lanes_pieces, outline_piece

KINDS = ("road", "crossing", "sidewalk")  # lowest priority first
KERB_M = 0.15            # as the sample scenes' kerbs (blender/scenes/streets.py)
REGION_MARGIN_M = 5.0
SAME_ROAD_DEG = 20.0
MIN_GAP_DEG = 30.0
POLE_CLEARANCE_M = 1.0
POLE_STEP_M = 0.25
POLE_SEARCH_M = 80.0
MOUNT_REACH_M = 15.0     # no pole farther than this outside the InfraLOB
ORIGINS = ("net", "junction")
# A scene from a network runs at one frame per SUMO step of rls traffic generate's
# default step, 0.1 s (SUMO's own default --step-length is 1 s): 10 fps, so traffic
# imported into it keys each FCD step on its own frame, with no resampling.
STEP_S = 0.1
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
    notices: list = field(default_factory=list)  # what a user should hear (stderr)
    step_s: float = STEP_S  # the scene's frame period: one SUMO step

    @property
    def fps(self):
        return round(1.0 / self.step_s)

    def count(self, kind):
        return sum(p.kind == kind for p in self.pieces)


def ranked_junctions(net):
    """The network's junctions, the default first: signalised ones before the others,
    then the most incoming lanes, then the largest outline (ties: network order)."""
    order = sorted(range(len(net.junctions)), key=lambda i: (
        not net.junctions[i].signalised, -net.junctions[i].incoming_lanes,
        -_area(net.junctions[i].shape), i))
    return [net.junctions[i] for i in order]


def _describe(j):
    return f"{j.id} ({'signalised' if j.signalised else j.type}, {j.incoming_lanes} lanes in)"


def choose_junction(net, junction_id=None, notices=None):
    """The junction named, else the default (``ranked_junctions``' first); without a
    name, a line in ``notices`` says which was chosen, why, and lists the others."""
    if not net.junctions:
        raise InputError(f"{net.path} has no junctions (only internal nodes or none): "
                         "there is nothing to put an InfraLOB over")
    ranked = ranked_junctions(net)
    if junction_id is not None:
        j = net.junction(junction_id)
        if j is None:
            ids = [k.id for k in ranked]
            more = f", ... ({len(ids)} in all)" if len(ids) > LIST_IDS else ""
            raise InputError(f"no junction {junction_id!r} in {net.path}; junctions there "
                             f"(signalised first, then most lanes in): "
                             f"{', '.join(ids[:LIST_IDS])}{more}")
        return j
    best, others = ranked[0], ranked[1:]
    if notices is not None:
        why = ("the signalised junction with the most incoming lanes" if best.signalised
               else "the network has no signalised junction: the one with the most "
                    "incoming lanes")
        listed = ", ".join(_describe(k) for k in others[:LIST_IDS])
        more = f", ... ({len(others)} others in all)" if len(others) > LIST_IDS else ""
        notices.append(f"junction {_describe(best)}: {why}"
                       + (f"; others: {listed}{more}" if others else "")
                       + "; choose another with --junction ID")
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
    strips = [lane for lane in net.lanes if lane.kind != "walkingarea"]
    rings = iter(lanes_pieces([lane.shape - o for lane in strips],
                              [lane.width for lane in strips]))
    for lane in net.lanes:
        if lane.kind == "walkingarea":
            p = outline_piece(lane.shape - o, "sidewalk", lane.id)
            if p is not None:
                pieces.append(p)
            continue
        pieces += [Piece(lane.kind, r, lane.id) for r in next(rings)]
    return pieces


def build_layout(net, junction_id=None, origin="net"):
    if origin not in ORIGINS:
        raise InputError(f"--origin must be one of {', '.join(ORIGINS)}, got {origin!r}")
    notices = []
    j = choose_junction(net, junction_id, notices)
    if not net.lanes:
        raise InputError(f"{net.path} has no lanes: there are no roads to build")
    o = j.centre.copy() if origin == "junction" else np.zeros(2)
    check_extent(net, o, origin)
    pieces = surface_pieces(net, o)
    shape = (j.shape if len(j.shape) >= 3 else j.centre[None, :]) - o
    lo, hi = shape.min(axis=0) - REGION_MARGIN_M, shape.max(axis=0) + REGION_MARGIN_M
    region = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
    mounts = corner_mounts(j, pieces, j.centre - o, region, notices)
    return RoadLayout(pieces=pieces, junction=j, origin=o, region=region, mounts=mounts,
                      net_offset=net.net_offset, notices=notices)


def check_extent(net, o, origin):
    """``InputError`` for a lane or junction beyond ``extent.SPAN_M`` of the scene's
    origin ``o`` (a vertex at 1e15 m, say: its triangulation collapses)."""
    hint = ("; is a vertex of it wrong? Fix or remove it (SUMO's netedit)"
            if origin == "junction" else "; --origin junction puts the scene's origin "
            "at the junction, for a network in far coordinates (UTM without netOffset)")
    for lane in net.lanes:
        check_span(lane.shape - o, f"{net.path}: lane {lane.id}", hint)
    for j in net.junctions:
        check_span((j.shape if len(j.shape) else j.centre[None, :]) - o,
                   f"{net.path}: junction {j.id}", hint)


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


def reach(centre, u, region, margin=MOUNT_REACH_M):
    """How far (m) from ``centre`` along the unit vector ``u`` the box ``region`` (x0,
    x1, y0, y1) grown by ``margin`` reaches."""
    x0, x1, y0, y1 = region
    lo = np.array([x0 - margin, y0 - margin])
    hi = np.array([x1 + margin, y1 + margin])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(u > 0, (hi - centre) / u, np.where(u < 0, (lo - centre) / u, np.inf))
    return float(max(0.0, np.min(t)))


def corner_mounts(junction, pieces, centre, region, notices=None):
    """A mount per corner of the junction (see the module's conventions); a corner
    with no clear ground within ``MOUNT_REACH_M`` of ``region`` gets none, and a line
    in ``notices``."""
    lo = np.array([p.ring.min(axis=0) for p in pieces]).reshape(-1, 2)
    hi = np.array([p.ring.max(axis=0) for p in pieces]).reshape(-1, 2)
    reach_box = ((lo <= centre + POLE_SEARCH_M) & (hi >= centre - POLE_SEARCH_M)).all(axis=1)
    near = [pieces[i] for i in np.flatnonzero(reach_box)]  # every piece a ray can meet
    paved = [p for p in near if p.kind in ("road", "crossing")]
    walks = [p for p in near if p.kind == "sidewalk"]
    ts = np.arange(0.0, POLE_SEARCH_M, POLE_STEP_M)
    span = int(np.ceil(2 * POLE_CLEARANCE_M / POLE_STEP_M)) + 1
    mounts = []
    for a in road_gaps(junction.roads):
        u = np.array([np.cos(a), np.sin(a)])
        compass = COMPASS[int(np.round(a / (np.pi / 4))) % 8]
        ray = centre + ts[:, None] * u
        off = ~_inside(ray, paved) | _inside(ray, walks)  # sidewalks win
        clear = np.array([off[i:i + span].all() for i in range(len(ts) - span)])
        first = np.flatnonzero(clear & (ts[:len(clear)] + POLE_CLEARANCE_M
                                        <= reach(centre, u, region)))
        if not len(first):
            if notices is not None:
                notices.append(
                    f"junction {junction.id}: no pole in its {compass} gap (bearing "
                    f"{np.degrees(a):.0f} deg): the ground is paved all the way to "
                    f"{MOUNT_REACH_M:g} m beyond the InfraLOB")
            continue
        xy = centre + (ts[first[0]] + POLE_CLEARANCE_M) * u
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
