"""Road scenes from SUMO networks, the core half: lanes and outlines as pieces (shapely
as the oracle), reading networks and their errors, the junction, origin, region and
corner mounts."""

import sys

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.metrics.polygon import points_in_polygon, shoelace_area
from rls_addon.core.roads.layout import (
    KINDS,
    POLE_CLEARANCE_M,
    REGION_MARGIN_M,
    build_layout,
    road_gaps,
)
from rls_addon.core.roads.network import read_network
from rls_addon.core.roads.pieces import lane_pieces, outline_piece
from tests.core.external_tools import require_module
from tests.sumo_nets import grid_net, osm_net, run_sumo_binary

try:  # the oracle: required by the fixture below (a skip, or a failure under make test)
    import shapely
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union
except ImportError:
    shapely = None


@pytest.fixture(autouse=True, scope="module")
def _shapely():
    require_module("shapely", "shapely==2.2.0")


def union_of(pieces):
    return unary_union([Polygon(p) for p in pieces])


def convex_ccw(ring):
    a, b, c = ring, np.roll(ring, -1, axis=0), np.roll(ring, -2, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - b[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - b[:, 0])
    return bool(np.all(cross >= -1e-9)) and shoelace_area(ring) > 0


@pytest.mark.parametrize("turn_deg, join", [(0, "mitre"), (30, "mitre"), (89, "mitre"),
                                            (-60, "mitre"), (120, "bevel"), (-150, "bevel")])
def test_a_bent_lane_is_its_mitred_outline(turn_deg, join):
    """Union of the pieces = shapely's flat-capped buffer with SUMO's mitred joins
    (bevelled beyond MITER_LIMIT_DEG), for one bend of each size."""
    t = np.radians(turn_deg)
    shape = [(0.0, 0.0), (20.0, 0.0), (20.0 + 15 * np.cos(t), 15 * np.sin(t))]
    pieces = lane_pieces(shape, 3.2)
    assert all(convex_ccw(p) for p in pieces)
    oracle = LineString(shape).buffer(1.6, cap_style="flat", join_style=join, mitre_limit=10)
    got = union_of(pieces)
    assert got.symmetric_difference(oracle).area < 1e-6 * oracle.area
    assert oracle.area > 35 * 3.2 * 0.9


def test_a_straight_lane_is_one_rectangle():
    pieces = lane_pieces([(0, 0), (10, 0), (10, 0), (30, 0)], 3.0)  # a repeated point too
    assert union_of(pieces).area == pytest.approx(90.0, rel=1e-12)


def test_a_bend_tighter_than_half_the_width_is_the_swept_union():
    """A hairpin of 1 m radius on a 4 m wide lane: SUMO's outline would cross itself;
    the pieces are convex and their union is the area the lane sweeps."""
    a = np.linspace(-np.pi / 2, np.pi / 2, 9)
    shape = np.r_[[(-20.0, -1.0)], np.c_[np.cos(a), np.sin(a)], [(-20.0, 1.0)]]
    pieces = lane_pieces(shape, 4.0)
    assert all(convex_ccw(p) for p in pieces)
    sweep = unary_union([LineString(shape[i:i + 2]).buffer(2.0, cap_style="flat")
                         for i in range(len(shape) - 1)] +
                        [LineString(shape[i - 1:i + 2]).buffer(2.0, cap_style="flat",
                                                               join_style="mitre")
                         for i in range(1, len(shape) - 1)])
    got = union_of(pieces)
    assert got.symmetric_difference(sweep).area < 1e-6 * sweep.area
    # the outline SUMO would draw (sumolib's move2side either side) crosses itself here
    from sumolib.geomhelper import move2side

    pts = [tuple(p) for p in shape]
    outline = Polygon(list(move2side(pts, 2.0)) + list(move2side(pts, -2.0))[::-1])
    assert not outline.is_valid


def test_outlines():
    square_cw = [(0, 0), (0, 2), (2, 2), (2, 0), (0, 0)]  # closed, clockwise
    p = outline_piece(square_cw, "road", "J")
    assert p.simple and len(p.ring) == 4 and shoelace_area(p.ring) == pytest.approx(4.0)
    bowtie = outline_piece([(0, 0), (2, 2), (2, 0), (0, 2)], "road", "J")
    assert bowtie is not None and not bowtie.simple
    assert outline_piece([(0, 0), (1, 1), (2, 2)], "road", "J") is None
    assert outline_piece([(0, 0), (1, 1)], "road", "J") is None


def test_road_gaps():
    four = [np.array(v, float) for v in ((1, 0), (0, 1), (-1, 0), (0, -1))]
    assert np.degrees(road_gaps(four)) == pytest.approx([45, 135, 225, 315])
    # both ways of one road (within 20 degrees) are one road
    two_way = [np.array((np.cos(a), np.sin(a))) for a in np.radians([-5, 5, 175, 185])]
    assert np.degrees(road_gaps(two_way)) == pytest.approx([90, 270])
    assert np.degrees(road_gaps([np.array((1.0, 0.0))])) == pytest.approx([180])


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    return grid_net(tmp_path_factory.mktemp("grid"))


def test_grid_network_and_layout(grid):
    net = read_network(grid)
    kinds = {lane.kind for lane in net.lanes}
    assert kinds == {"road", "sidewalk", "crossing", "walkingarea"}
    assert len(net.junctions) == 9
    lay = build_layout(net)
    assert lay.junction.id == "B1"  # the four-way middle one is the largest
    assert np.allclose(lay.origin, 0)
    x0, x1, y0, y1 = lay.region
    shape = lay.junction.shape
    assert (x0, y0) == pytest.approx(shape.min(axis=0) - REGION_MARGIN_M)
    assert (x1, y1) == pytest.approx(shape.max(axis=0) + REGION_MARGIN_M)
    assert {lay.count(k) > 0 for k in KINDS} == {True}
    # a pole at each of the four corners, on the sidewalk, off the road, in the region
    assert len(lay.mounts) == 4 and all(m.on_sidewalk for m in lay.mounts)
    paved = [p.ring for p in lay.pieces if p.kind in ("road", "crossing")]
    walks = [p.ring for p in lay.pieces if p.kind == "sidewalk"]
    for m in lay.mounts:
        d = m.xy - lay.junction.centre
        assert abs(abs(d[0]) - abs(d[1])) < 0.5  # on a diagonal of the square grid
        assert any(points_in_polygon(m.xy[None], r)[0] for r in walks)
        # between the junction's centre and the pole: road first, then sidewalk only
        ray = lay.junction.centre + np.linspace(0, 1, 200)[:, None] * d
        paved_on = np.any([points_in_polygon(ray, r) for r in paved], axis=0)
        walk_on = np.any([points_in_polygon(ray, r) for r in walks], axis=0)
        assert paved_on[0] and not walk_on[0] and walk_on[-1]
        assert x0 < m.xy[0] < x1 and y0 < m.xy[1] < y1
        # the clearance: a step back towards the junction is still sidewalk
        back = m.xy - POLE_CLEARANCE_M * 0.9 * d / np.linalg.norm(d)
        assert any(points_in_polygon(back[None], r)[0] for r in walks)
    assert sorted(m.name for m in lay.mounts) == ["Pole NE B1", "Pole NW B1", "Pole SE B1",
                                                  "Pole SW B1"]


def test_origin_at_the_junction_shifts_everything(grid):
    net = read_network(grid)
    a, b = build_layout(net, "A1"), build_layout(net, "A1", origin="junction")
    assert np.allclose(b.origin, a.junction.centre)
    assert np.allclose(np.array(a.region) - np.repeat(b.origin, 2), b.region)
    assert all(np.allclose(p.ring - b.origin, q.ring) for p, q in zip(a.pieces, b.pieces))
    assert all(np.allclose(m.xy - b.origin, n.xy) for m, n in zip(a.mounts, b.mounts))


def test_osm_network_reads(tmp_path):
    net = read_network(osm_net(tmp_path))
    assert net.net_offset[0] != 0  # UTM, shifted by netconvert
    lay = build_layout(net)
    assert lay.count("crossing") and lay.count("sidewalk") and len(lay.mounts) >= 3


def test_junction_not_found_lists_ids(grid):
    with pytest.raises(InputError, match=r"no junction 'nope' .*most lanes in\): B1, "):
        build_layout(read_network(grid), "nope")
    with pytest.raises(InputError, match="--origin"):
        build_layout(read_network(grid), origin="centre")


NO_JUNCTIONS = """<?xml version="1.0" encoding="UTF-8"?>
<net version="1.20" junctionCornerDetail="5" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
    <location netOffset="0.00,0.00" convBoundary="0.00,0.00,100.00,0.00" origBoundary="0.00,0.00,100.00,0.00" projParameter="!"/>
</net>
"""

ELEVATED = """<?xml version="1.0" encoding="UTF-8"?>
<net version="1.20">
    <location netOffset="0.00,0.00" convBoundary="0.00,0.00,100.00,0.00" origBoundary="0.00,0.00,100.00,0.00" projParameter="!"/>
    <edge id="a" from="J0" to="J1" priority="1">
        <lane id="a_0" index="0" speed="13.89" length="100.00" shape="0.00,0.00,4.00 100.00,0.00,6.00"/>
    </edge>
    <junction id="J0" type="dead_end" x="0.00" y="0.00" z="4.00" incLanes="" intLanes="" shape="0.00,0.00,4.00 0.00,-3.20,4.00"/>
    <junction id="J1" type="dead_end" x="100.00" y="0.00" z="6.00" incLanes="a_0" intLanes="" shape="100.00,0.00,6.00 100.00,-3.20,6.00"/>
</net>
"""


def test_bad_networks(tmp_path, grid):
    with pytest.raises(InputError, match="not found"):
        read_network(tmp_path / "missing.net.xml")
    bad = tmp_path / "bad.net.xml"
    bad.write_text("this is not XML")
    with pytest.raises(InputError, match="not a well-formed SUMO network"):
        read_network(bad)
    other = tmp_path / "routes.xml"
    other.write_text("<routes><vehicle id='v' depart='0'/></routes>")
    with pytest.raises(InputError, match="root element is <routes>, not <net>"):
        read_network(other)
    cut = tmp_path / "cut.net.xml"
    text = grid.read_text()
    cut.write_text(text[:len(text) // 2])
    with pytest.raises(InputError, match="truncated"):
        read_network(cut)
    empty = tmp_path / "empty.net.xml"
    empty.write_text(NO_JUNCTIONS)
    with pytest.raises(InputError, match="has no junctions"):
        build_layout(read_network(empty))
    high = tmp_path / "high.net.xml"
    high.write_text(ELEVATED)
    with pytest.raises(InputError, match=r"elevation .*--flatten"):
        read_network(high)
    assert high.read_text() == ELEVATED  # only read


def test_no_junctions_is_its_own_error(tmp_path):
    from rls_addon.core.roads.layout import choose_junction
    from rls_addon.core.roads.network import RoadNetwork

    with pytest.raises(InputError, match="has no junctions"):
        choose_junction(RoadNetwork(path="x.net.xml", lanes=[], junctions=[]))


def test_sumolib_missing(monkeypatch, grid):
    monkeypatch.setitem(sys.modules, "sumolib", None)
    monkeypatch.setitem(sys.modules, "sumolib.net", None)
    with pytest.raises(InputError, match="pip install sumolib"):
        read_network(grid)


def outside_region(xy, region):
    """How far (m) ``xy`` lies outside the box ``region`` (x0, x1, y0, y1); 0 inside."""
    x0, x1, y0, y1 = region
    return float(np.hypot(max(x0 - xy[0], 0.0, xy[0] - x1), max(y0 - xy[1], 0.0, xy[1] - y1)))


def test_poles_stand_at_the_chosen_junction_only(tmp_path):
    """On the OSM fixture, junctions '1' and '6' have a gap between two roads that runs
    along a road (its two ways diverge): the search along that bisector found no clear
    ground and put a pole 68-73 m away, at the far end of the road. Every pole of every
    junction is now within MOUNT_REACH_M (15 m) of the InfraLOB, and a gap with no
    clear ground within reach gets no pole and a notice naming it."""
    net = read_network(osm_net(tmp_path))
    told = 0
    for j in net.junctions:
        lay = build_layout(net, j.id)
        for m in lay.mounts:
            assert outside_region(m.xy, lay.region) <= 15.0, (j.id, m.name, m.xy)
        told += sum(f"junction {j.id}" in n and "no pole" in n for n in lay.notices)
    lay1 = build_layout(net, "1")
    assert len(lay1.mounts) >= 4  # the four real corners keep their poles
    assert all(m.on_sidewalk for m in lay1.mounts)
    assert told >= 2


def test_a_junction_with_no_area_is_read(tmp_path):
    """Two edges meeting end to end at a priority node: netconvert writes the internal
    lane between them as two equal points (``length="0.10"``), as it does wherever a
    way is split without a junction area (OpenStreetMap networks). The whole network was
    refused ("lane :C_0_0 has a shape of 2 point(s) but no length"); such a lane covers
    no ground and is left out."""
    (tmp_path / "n.nod.xml").write_text(
        '<nodes><node id="A" x="0" y="0" type="priority"/><node id="C" x="100" y="0" '
        'type="priority"/><node id="D" x="200" y="0" type="priority"/></nodes>')
    (tmp_path / "n.edg.xml").write_text(
        '<edges><edge id="AC" from="A" to="C" numLanes="1"/>'
        '<edge id="CD" from="C" to="D" numLanes="1"/></edges>')
    out = tmp_path / "n.net.xml"
    run_sumo_binary("netconvert", "--node-files", tmp_path / "n.nod.xml", "--edge-files",
                    tmp_path / "n.edg.xml", "-o", out)
    assert 'id=":C_0_0"' in out.read_text()
    net = read_network(out)
    assert sorted(lane.id for lane in net.lanes) == ["AC_0", "CD_0"]
    assert build_layout(net, "C").junction.id == "C"


def test_the_default_junction_is_the_signalised_one(tmp_path):
    """A 3 x 3 grid with one traffic light, at its corner A0: the default junction is A0
    (it was B1, the largest by area, a priority junction), and the notice names it and
    lists the others."""
    net = read_network(grid_net(tmp_path, "--tls.set", "A0"))
    lay = build_layout(net)
    assert lay.junction.id == "A0" and lay.junction.signalised
    told = [n for n in lay.notices if n.startswith("junction A0")]
    assert told and "signalised" in told[0] and "B1 (priority, 4 lanes in)" in told[0]


def test_the_default_junction_has_the_most_incoming_lanes():
    """Among signalised junctions the one with the most lanes coming in wins over a
    larger one; an unsignalised one with more lanes and area loses to both; without a
    signalised junction the most lanes in wins and the notice says there is none."""
    from rls_addon.core.roads.layout import choose_junction
    from rls_addon.core.roads.network import Junction, RoadNetwork

    def square(half):
        return np.array([(-half, -half), (half, -half), (half, half), (-half, half)])

    js = [Junction("big", "traffic_light", np.zeros(2), square(12.0), incoming_lanes=8),
          Junction("busy", "traffic_light_right_on_red", np.zeros(2), square(8.0),
                   incoming_lanes=12),
          Junction("plain", "priority", np.zeros(2), square(20.0), incoming_lanes=16)]
    notices = []
    assert choose_junction(RoadNetwork("n.net.xml", [], js), None, notices).id == "busy"
    assert "big (signalised, 8 lanes in), plain (priority, 16 lanes in)" in notices[0]
    notices = []
    unsignalised = [Junction(j.id, "priority", j.centre, j.shape,
                             incoming_lanes=j.incoming_lanes) for j in js]
    assert choose_junction(RoadNetwork("n.net.xml", [], unsignalised), None,
                           notices).id == "plain"
    assert "no signalised junction" in notices[0]


BAD_LANES = [
    # (what is changed in lane A0B0_0's or A0B0_1's line, words of the error)
    ('width="2.00" shape="5.20,-4.20 72.80,-4.20"', 'width="nan" shape="5.20,-4.20 72.80,-4.20"',
     r"lane A0B0_0 has width 'nan'|lane A0B0_0 has width nan"),
    ('width="2.00" shape="5.20,-4.20 72.80,-4.20"', 'width="-2.00" shape="5.20,-4.20 72.80,-4.20"',
     r"lane A0B0_0 has width -2"),
    ('width="2.00" shape="5.20,-4.20 72.80,-4.20"', 'width="2.00" shape="5.20,-4.20"',
     r"lane A0B0_0 has a shape of 1 point\(s\) but no length"),
    ('shape="5.20,-1.60 72.80,-1.60"', 'shape="5.20,-1.60 1e15,-1.60"',
     r"lane A0B0_1 lies 1e\+15 m from the scene's origin: RLS takes coordinates within "
     r"100000 m of the scene's origin \(Blender stores coordinates as float32"),
]


@pytest.mark.parametrize("old, new, words", BAD_LANES)
def test_a_bad_lane_is_refused_naming_it(grid, tmp_path, old, new, words):
    """A lane whose width is NaN or negative, whose shape is one point, or with a vertex
    at 1e15 m: each was dropped without a word (or, at 1e15, collapsed the whole
    triangulation to 0 triangles); now one error names the lane."""
    text = grid.read_text()
    assert text.count(old) == 1
    bad = tmp_path / "bad.net.xml"
    bad.write_text(text.replace(old, new))
    with pytest.raises(InputError, match=words):
        build_layout(read_network(bad))
    with pytest.raises(InputError, match=words):
        build_layout(read_network(bad), origin="junction")


def test_far_coordinates_are_fine_with_the_origin_at_the_junction(grid, tmp_path):
    """A network 3e6 m from (0, 0), as UTM without netconvert's normalisation: refused
    with the origin at the network's (0, 0), built with --origin junction."""
    import re

    text = grid.read_text()
    shift = lambda m: f"{float(m.group(1)) + 3e6:.2f},{float(m.group(2)):.2f}"  # noqa: E731
    far = re.sub(r'(?<=shape=")[^"]*', lambda m: re.sub(r"(-?[\d.]+),(-?[\d.]+)", shift,
                                                       m.group(0)), text)
    far = re.sub(r'(<junction [^>]*\bx=")([\d.]+)',
                 lambda m: m.group(1) + f"{float(m.group(2)) + 3e6:.2f}", far)
    path = tmp_path / "far.net.xml"
    path.write_text(far)
    with pytest.raises(InputError, match="--origin junction puts"):
        build_layout(read_network(path))
    lay = build_layout(read_network(path), origin="junction")
    assert lay.junction.id == "B1" and len(lay.mounts) == 4


NO_JUNCTION_ELEMENTS = """<?xml version="1.0" encoding="UTF-8"?>
<net version="1.20">
    <location netOffset="0.00,0.00" convBoundary="0.00,0.00,100.00,0.00" origBoundary="0.00,0.00,100.00,0.00" projParameter="!"/>
    <edge id="a" from="J0" to="J1" priority="1">
        <lane id="a_0" index="0" speed="13.89" length="100.00" shape="0.00,0.00 100.00,0.00"/>
    </edge>
</net>
"""


def test_a_network_without_junction_elements_is_one_error(tmp_path):
    """Edges naming junctions that no <junction> defines: a TypeError from sumolib's
    node without a position before; now an InputError naming the junction."""
    path = tmp_path / "nojunctions.net.xml"
    path.write_text(NO_JUNCTION_ELEMENTS)
    with pytest.raises(InputError, match=r"junction 'J0' is named by edge 'a' but has no "
                                         r"<junction> element"):
        read_network(path)
