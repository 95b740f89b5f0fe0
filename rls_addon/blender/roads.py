"""A scene from a SUMO network's plan (``core.roads.layout.RoadLayout``): road,
crossing and sidewalk surfaces, kerbs, corner mount poles and the InfraLOB, with
``bpy.data`` only (no operators).

The surfaces are one constrained Delaunay triangulation of every piece's edges at once
(Blender's ``mathutils.geometry.delaunay_2d_cdt``): edges are split where they cross,
so each triangle lies wholly inside or outside each piece; it is kept when its
centroid lies in a piece (the even-odd inside of the piece's outline, which for an
outline that crosses itself is the documented rule), with the kind that wins there
(sidewalk over crossing over road). So overlapping lanes and junction shapes make one
surface without doubled faces, and the meshes' union is the pieces' union.

Objects (labels from their collections, see ``core/labels.py``):

* ``Road`` (collection Road): lanes, internal lanes and junction shapes at z = 0;
* ``Crossings`` (collection Road): pedestrian crossings at z = 0;
* ``Sidewalk`` (collection Sidewalk): sidewalks and walking areas at z = ``KERB_M``;
* ``Kerbs`` (collection Sidewalk): the sidewalks' edges, vertical faces 0 to ``KERB_M``;
* ``Pole ...`` (collection Poles): one per corner of the junction, ``rls_mount``;
* ``InfraLOB`` (collection Regions): ``rls_infralob``, over the junction.

The scene runs at one frame per SUMO step (``layout.step_s``, 0.1 s: 10 fps).
"""


import bpy
import numpy as np
from mathutils import Vector
from mathutils.geometry import delaunay_2d_cdt

from ..core.metrics.polygon import points_in_polygon
from ..core.roads.layout import KERB_M, KINDS
from .scenes.build import collection, infralob, material, mount_pole, standard_materials

POLE_HEIGHT_M = 6.0
MIN_KERB_M = 1e-3  # shorter sidewalk edges (slivers of the triangulation) get no kerb face
CDT_EPSILON_M = 1e-4
OUTPUT_CONVEX_HULL = 0  # delaunay_2d_cdt's output_type: every triangle of the hull


def triangulate(pieces):
    """(V, 2) float64 vertices, (T, 3) counter-clockwise triangles and (T,) kind index
    (into ``KINDS``) of the union of ``pieces``."""
    if not pieces:
        return np.zeros((0, 2)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    allpts = np.concatenate([p.ring for p in pieces])
    centre = 0.5 * (allpts.min(axis=0) + allpts.max(axis=0))  # float32 Vectors: stay small
    verts, edges = [], []
    for p in pieces:
        start = len(verts)
        verts += [Vector(v) for v in (p.ring - centre)]
        n = len(p.ring)
        edges += [(start + i, start + (i + 1) % n) for i in range(n)]
    out_v, _, out_f, _, _, _ = delaunay_2d_cdt(verts, edges, [], OUTPUT_CONVEX_HULL,
                                               CDT_EPSILON_M, False)
    v = np.array([tuple(c) for c in out_v], dtype=np.float64).reshape(-1, 2) + centre
    tris = np.array(out_f, dtype=np.int64).reshape(-1, 3)
    kind = classify(v[tris].mean(axis=1), pieces)
    keep = kind >= 0
    tris, kind = tris[keep], kind[keep]
    a, b, c = (v[tris[:, i]] for i in range(3))
    cw = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    tris[cw] = tris[cw][:, ::-1]
    return v, tris, kind


def classify(points, pieces):
    """Per point (a triangle's centroid), the index in ``KINDS`` of the highest kind of
    piece it lies in (even-odd inside of the piece's outline), -1 for none. Every
    piece's edges are edges of the triangulation, so a triangle lies wholly inside or
    wholly outside each piece and its centroid decides."""
    rank = {kind: i for i, kind in enumerate(KINDS)}
    kind = np.full(len(points), -1, dtype=np.int64)
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    for p in pieces:
        lo, hi = p.ring.min(axis=0), p.ring.max(axis=0)
        cand = order[np.searchsorted(xs, lo[0]):np.searchsorted(xs, hi[0], side="right")]
        cand = cand[(points[cand, 1] >= lo[1]) & (points[cand, 1] <= hi[1])]
        if not len(cand):
            continue
        inside = cand[points_in_polygon(points[cand], p.ring)]
        kind[inside] = np.maximum(kind[inside], rank[p.kind])
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


def mesh_object(coll, name, verts, faces, mat):
    """A mesh object from (V, 3) ``verts`` and (F, k) ``faces`` (bulk foreach_set)."""
    verts = np.asarray(verts, dtype=np.float32).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int32)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.ravel())
    if len(faces):
        k = faces.shape[1]
        mesh.loops.add(faces.size)
        mesh.loops.foreach_set("vertex_index", faces.ravel())
        mesh.polygons.add(len(faces))
        mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, k, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.validate(verbose=False)
    if mat is not None:
        mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    coll.objects.link(obj)
    return obj


def _compact(v2, tris, z):
    used, inv = np.unique(tris.ravel(), return_inverse=True)
    return np.c_[v2[used], np.full(len(used), z)], inv.reshape(tris.shape)


def build_roads(scene, layout, progress=None):
    """Fill ``scene`` (empty) with the layout's surfaces, kerbs, mounts and region;
    return a summary dict."""
    say = progress or (lambda text: None)
    mats = standard_materials()
    paint = material("Crossing paint", (0.85, 0.85, 0.82), reflectivity=0.6)
    colls = {n: collection(scene, n) for n in ("Road", "Sidewalk", "Poles")}
    say(f"triangulating {len(layout.pieces)} pieces")
    v2, tris, kind = triangulate(layout.pieces)
    say(f"meshes from {len(tris)} triangles")
    made = {}
    for name, k, coll, z, mat in (("Road", "road", "Road", 0.0, mats["asphalt"]),
                                  ("Crossings", "crossing", "Road", 0.0, paint),
                                  ("Sidewalk", "sidewalk", "Sidewalk", KERB_M, mats["concrete"])):
        sel = tris[kind == KINDS.index(k)]
        if len(sel):
            verts, faces = _compact(v2, sel, z)
            made[name] = mesh_object(colls[coll], name, verts, faces, mat)
    walk = tris[kind == KINDS.index("sidewalk")]
    edges = boundary_edges(walk)
    edges = edges[np.linalg.norm(v2[edges[:, 1]] - v2[edges[:, 0]], axis=1) >= MIN_KERB_M]
    if len(edges):
        a, b = v2[edges[:, 0]], v2[edges[:, 1]]
        n = len(edges)
        verts = np.concatenate([np.c_[a, np.zeros(n)], np.c_[b, np.zeros(n)],
                                np.c_[b, np.full(n, KERB_M)], np.c_[a, np.full(n, KERB_M)]])
        i = np.arange(n)
        faces = np.c_[i, i + n, i + 2 * n, i + 3 * n]  # outward: to the right of a -> b
        made["Kerbs"] = mesh_object(colls["Sidewalk"], "Kerbs", verts, faces, mats["concrete"])
    mounts = []
    for m in layout.mounts:
        pole = mount_pole(colls["Poles"], m.name, float(m.xy[0]), float(m.xy[1]),
                          POLE_HEIGHT_M, mats["steel"], "junction_corner",
                          base_z=KERB_M if m.on_sidewalk else 0.0)
        pole["rls_sumo_junction"] = layout.junction.id
        mounts.append(pole.name)
    x0, x1, y0, y1 = layout.region
    lob = infralob(scene, "InfraLOB", x0, x1, y0, y1)
    lob["rls_sumo_junction"] = layout.junction.id
    scene["rls_sumo_origin"] = [float(v) for v in layout.origin]
    scene["rls_sumo_net_offset"] = [float(v) for v in layout.net_offset]
    scene["rls_sumo_junction"] = layout.junction.id
    scene.render.fps, scene.render.fps_base = layout.fps, 1.0
    scene["rls_sumo_step_s"] = float(layout.step_s)
    return {"junction": layout.junction.id, "origin": [float(v) for v in layout.origin],
            "net_offset": list(layout.net_offset), "infralob": lob.name,
            "region": [round(float(v), 3) for v in layout.region], "mounts": mounts,
            "objects": sorted(made), "triangles": int(len(tris)), "fps": layout.fps,
            "pieces": {k: layout.count(k) for k in KINDS}}
