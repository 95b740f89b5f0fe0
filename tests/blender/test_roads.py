"""Road scenes from SUMO networks, the Blender half: the triangulation (union, kinds,
outlines that cross themselves), the objects, labels, kerbs, mounts and region, and
the written .blend read back: its road meshes cover the network's lanes (shapely as
the oracle, with lane polygons made here from sumolib's shapes and widths)."""

import os

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from rls_addon.core.errors import OutputError  # noqa: E402
from rls_addon.core.roads.layout import KERB_M, KINDS, build_layout  # noqa: E402
from rls_addon.core.roads.network import read_network  # noqa: E402
from rls_addon.core.roads.pieces import Piece, outline_piece  # noqa: E402
from tests.core.external_tools import require_module  # noqa: E402
from tests.sumo_nets import grid_net, osm_net  # noqa: E402

try:  # the oracle: required by the fixture below (a skip, or a failure under make test)
    import shapely
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union
except ImportError:
    shapely = None


@pytest.fixture(autouse=True, scope="module")
def _shapely():
    require_module("shapely", "shapely==2.2.0")

SURFACES = ("Road", "Crossings", "Sidewalk")


def tri_union(v, tris):
    return unary_union([Polygon(v[t]) for t in tris])


def square(x0, y0, size, kind):
    return Piece(kind, np.array([(x0, y0), (x0 + size, y0), (x0 + size, y0 + size),
                                 (x0, y0 + size)], float), "test")


def test_overlapping_pieces_make_one_surface_the_higher_kind_wins():
    from rls_addon.blender.roads import triangulate

    v, tris, kind = triangulate([square(0, 0, 2, "road"), square(1, 1, 2, "sidewalk"),
                                 square(10, 0, 1, "crossing"), square(10.5, 0, 1, "road")])
    area = {k: tri_union(v, tris[kind == i]).area for i, k in enumerate(KINDS)}
    assert area["road"] == pytest.approx(3.0 + 0.5, abs=1e-6)
    assert area["sidewalk"] == pytest.approx(4.0, abs=1e-6)
    assert area["crossing"] == pytest.approx(1.0, abs=1e-6)
    # no doubled faces: the triangles' areas add up to the union's
    a, b, c = (v[tris[:, i]] for i in range(3))
    signed = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    assert (signed > 0).all() and signed.sum() == pytest.approx(7.0 + 1.5, abs=1e-6)


def test_an_outline_that_crosses_itself_is_its_even_odd_inside():
    from rls_addon.blender.roads import triangulate

    bowtie = outline_piece([(0, 0), (2, 2), (2, 0), (0, 2)], "road", "J")
    assert not bowtie.simple
    v, tris, kind = triangulate([bowtie, square(5, 5, 1, "road")])
    got = tri_union(v, tris)
    assert got.area == pytest.approx(2.0 + 1.0, abs=1e-6)  # two triangles of 1 m^2 + the square
    assert got.contains(shapely.Point(0.5, 1.0)) and not got.contains(shapely.Point(1.0, 0.5))


def lane_union(net_path):
    """The oracle: every lane's polygon from sumolib (flat-capped mitred buffer of its
    centre line; walking areas are outlines), unioned by shapely."""
    import sumolib

    net = sumolib.net.readNet(str(net_path), withInternal=True, withPedestrianConnections=True)
    polys, junctions = [], []
    for e in net.getEdges(withInternal=True):
        for lane in e.getLanes():
            s = lane.getShape()
            if e.getFunction() == "walkingarea":
                polys.append(Polygon(s).buffer(0))
            elif len(s) >= 2:
                polys.append(LineString(s).buffer(lane.getWidth() / 2, cap_style="flat",
                                                  join_style="mitre"))
    for n in net.getNodes():
        if len(n.getShape()) >= 3:
            junctions.append(Polygon(n.getShape()).buffer(0))
    return unary_union(polys), unary_union(junctions)


def written_scene(folder, net, **kw):
    from rls_addon.blender.files import save_blend
    from rls_addon.blender.roads import build_roads

    layout = build_layout(read_network(net), **kw)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    info = build_roads(bpy.context.scene, layout)
    path = folder / "roads.blend"
    save_blend(path)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    return layout, info, path


def mesh_union(names, origin):
    tris = []
    for name in names:
        ob = bpy.data.objects.get(name)
        if ob is None:
            continue
        co = np.array([(ob.matrix_world @ v.co)[:] for v in ob.data.vertices])
        for p in ob.data.polygons:
            tris.append(Polygon(co[list(p.vertices), :2] + origin))
    return unary_union(tris)


@pytest.mark.parametrize("which", ["grid", "osm"])
def test_written_scene_covers_the_lanes(tmp_path, scene, which):
    from rls_addon.blender.labels import object_label
    from rls_addon.blender.region import is_lob, lob_polygon_world
    from rls_addon.blender.scenes.build import is_mount, mount_position
    from rls_addon.core.labels import NAME_TO_ID

    net = grid_net(tmp_path) if which == "grid" else osm_net(tmp_path)
    before = net.read_bytes()
    layout, info, path = written_scene(tmp_path, net, origin="junction")
    assert net.read_bytes() == before
    assert [p for p in os.listdir(tmp_path) if ".rls-" in p] == []  # no temporaries left
    origin = np.array(bpy.context.scene["rls_sumo_origin"])
    assert np.allclose(origin, layout.junction.centre)
    mesh = mesh_union(SURFACES, origin)
    lanes, junctions = lane_union(net)
    # the test: the meshes' area within 2 % of the lanes' union ...
    assert abs(mesh.area - lanes.area) < 0.02 * lanes.area
    # ... and the lanes covered, nothing beyond the lanes and the junction shapes
    assert lanes.difference(mesh).area < 1e-3 * lanes.area
    assert mesh.difference(unary_union([lanes, junctions])).area < 1e-3 * lanes.area
    # labels by collection; heights: roads at 0, sidewalks on the kerb
    label = {n: object_label(bpy.data.objects[n]) for n in (*SURFACES, "Kerbs")}
    assert label == {"Road": NAME_TO_ID["road"], "Crossings": NAME_TO_ID["road"],
                     "Sidewalk": NAME_TO_ID["sidewalk"], "Kerbs": NAME_TO_ID["sidewalk"]}
    for name, z in (("Road", 0.0), ("Crossings", 0.0), ("Sidewalk", KERB_M)):
        co = np.array([v.co[:] for v in bpy.data.objects[name].data.vertices])
        assert np.allclose(co[:, 2], z)
    kerbs = bpy.data.objects["Kerbs"].data
    for p in kerbs.polygons:
        assert abs(p.normal.z) < 1e-6  # vertical
    kz = np.array([v.co.z for v in kerbs.vertices])
    assert set(np.round(kz, 6)) == {0.0, round(KERB_M, 6)}
    # mounts at the junction's corners, in its region; one InfraLOB
    mounts = [o for o in bpy.data.objects if is_mount(o)]
    assert sorted(o.name for o in mounts) == sorted(info["mounts"]) and len(mounts) >= 3
    lobs = [o for o in bpy.data.objects if is_lob(o)]
    assert [o.name for o in lobs] == ["InfraLOB"]
    poly = lob_polygon_world(lobs[0])
    region = Polygon(poly)
    assert region.contains(Polygon(layout.junction.shape - origin))
    planned = {m.name: m for m in layout.mounts}
    for o in mounts:
        x, y, z = mount_position(o)
        assert region.contains(shapely.Point(x, y))
        assert (x, y) == pytest.approx(tuple(planned[o.name].xy), abs=0.01)
        base = KERB_M if planned[o.name].on_sidewalk else 0.0
        assert z == pytest.approx(base + 6.0 + 0.25, abs=1e-4)
    assert any(m.on_sidewalk for m in layout.mounts)
    # it runs at rls traffic generate's default step, 0.1 s: one frame per SUMO step
    render = bpy.context.scene.render
    assert render.fps / render.fps_base == 10 and bpy.context.scene["rls_sumo_step_s"] == 0.1


def test_save_refuses_an_existing_file(tmp_path, scene):
    from rls_addon.blender.files import save_blend

    path = tmp_path / "s.blend"
    path.write_bytes(b"keep")
    with pytest.raises(OutputError, match="already exists"):
        save_blend(path)
    assert path.read_bytes() == b"keep"
    save_blend(path, overwrite=True)
    assert path.read_bytes()[:4] != b"keep" and os.listdir(tmp_path) == ["s.blend"]


def test_tiles_make_the_same_surface_and_no_kerbs_on_their_seams(tmp_path, scene):
    """The surface triangulated in 60 m tiles (the 3 x 3 grid is about 4 x 4 of them)
    is the one of a single tile that holds everything: the same union per kind (1e-6),
    the same sidewalk outline length (no kerb along a tile's side), and each tile's
    CDT holds only a part of the pieces (issue #38: one CDT of a 30 x 30 grid's
    1.3 million triangles took 2.9 GB)."""
    from rls_addon.blender.roads import cdt
    from rls_addon.core.roads import surface

    layout = build_layout(read_network(grid_net(tmp_path)))
    sizes = []

    def counting(points, edges, centre):
        sizes.append(len(points))
        return cdt(points, edges, centre)

    small = surface.triangulate(layout.pieces, counting, size=60.0)
    tiles = len(sizes)
    whole = surface.triangulate(layout.pieces, cdt, size=1e4)
    assert tiles >= 12 and max(sizes[:tiles]) < 0.5 * len(np.concatenate(
        [p.ring for p in layout.pieces]))
    for i, k in enumerate(KINDS):
        a = tri_union(small[0], small[1][small[2] == i])
        b = tri_union(whole[0], whole[1][whole[2] == i])
        assert a.symmetric_difference(b).area < 1e-6 * max(b.area, 1.0), k

    def kerb_length(v, t, kind, tiling):
        e = surface.kerb_edges(v, t, kind, tiling, 1e-3)
        return float(np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1).sum())

    assert kerb_length(*small) == pytest.approx(kerb_length(*whole), rel=1e-6)
    assert kerb_length(*whole) > 100.0
