"""A scene from a SUMO network's plan (``core.roads.layout.RoadLayout``): road,
crossing and sidewalk surfaces, kerbs, corner mount poles and the InfraLOB, with
``bpy.data`` only (no operators).

The surfaces are triangulated tile by tile in the core (``core.roads.surface``), with
Blender's constrained Delaunay triangulation (``mathutils.geometry.delaunay_2d_cdt``,
``cdt`` here) of each tile's piece edges: edges are split where they cross, so each
triangle lies wholly inside or outside each piece; it is kept with the kind that wins
there (sidewalk over crossing over road). So overlapping lanes and junction shapes make
one surface without doubled faces, and the meshes' union is the pieces' union.

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

from ..core.roads import surface
from ..core.roads.layout import KERB_M, KINDS
from .scenes.build import collection, infralob, material, mount_pole, standard_materials

POLE_HEIGHT_M = 6.0
MIN_KERB_M = 1e-3  # shorter sidewalk edges (slivers of the triangulation) get no kerb face
CDT_EPSILON_M = 1e-4
OUTPUT_CONVEX_HULL = 0  # delaunay_2d_cdt's output_type: every triangle of the hull


def cdt(points, edges, centre):
    """Blender's constrained Delaunay triangulation of ``points`` (n, 2) and ``edges``
    (m, 2), worked out relative to ``centre`` (its Vectors are float32: they stay
    small); (vertices (V, 2) float64, triangles (T, 3)) (``core.roads.surface``)."""
    verts = [Vector(p) for p in (np.asarray(points, np.float64) - centre)]
    out_v, _, out_f, _, _, _ = delaunay_2d_cdt(verts, [tuple(e) for e in edges.tolist()],
                                               [], OUTPUT_CONVEX_HULL, CDT_EPSILON_M, False)
    v = np.array([tuple(c) for c in out_v], dtype=np.float64).reshape(-1, 2) + centre
    return v, np.array(out_f, dtype=np.int64).reshape(-1, 3)


def triangulate(pieces, progress=None):
    """(V, 2) float64 vertices, (T, 3) counter-clockwise triangles and (T,) kind index
    (into ``KINDS``) of the union of ``pieces`` (``core.roads.surface.triangulate``)."""
    v, t, kind, _ = surface.triangulate(pieces, cdt, progress)
    return v, t, kind


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


def build_roads(scene, layout, progress=None, tiles=None):
    """Fill ``scene`` (empty) with the layout's surfaces, kerbs, mounts and region;
    return a summary dict. ``progress(text)`` hears the stages, ``tiles(done, total,
    seconds_left)`` each tile of the triangulation."""
    say = progress or (lambda text: None)
    mats = standard_materials()
    paint = material("Crossing paint", (0.85, 0.85, 0.82), reflectivity=0.6)
    colls = {n: collection(scene, n) for n in ("Road", "Sidewalk", "Poles")}
    say(f"triangulating {len(layout.pieces)} pieces")
    v2, tris, kind, tiling = surface.triangulate(layout.pieces, cdt, tiles)
    say(f"meshes from {len(tris)} triangles")
    made = {}
    for name, k, coll, z, mat in (("Road", "road", "Road", 0.0, mats["asphalt"]),
                                  ("Crossings", "crossing", "Road", 0.0, paint),
                                  ("Sidewalk", "sidewalk", "Sidewalk", KERB_M, mats["concrete"])):
        sel = tris[kind == KINDS.index(k)]
        if len(sel):
            verts, faces = _compact(v2, sel, z)
            made[name] = mesh_object(colls[coll], name, verts, faces, mat)
    edges = surface.kerb_edges(v2, tris, kind, tiling, MIN_KERB_M)
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


class BlenderRoadScene:
    """The Blender side of ``core.roads.scene.scene_from_net``: builds into ``scene``
    (empty) and saves the current file."""

    def __init__(self, scene):
        self.scene = scene

    def build(self, layout, say, tiles):
        return build_roads(self.scene, layout, progress=say, tiles=tiles)

    def save(self, out, overwrite):
        from .files import save_blend

        save_blend(out, overwrite=overwrite)
