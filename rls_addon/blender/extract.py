"""Scene extraction: evaluated depsgraph -> world-space ``SceneGeometry`` in bulk.

Reads every evaluated object instance (modifiers, geometry nodes, collection
instances, curves and text as meshes), skips objects hidden from render and objects
whose bounds lie beyond the sensor's range, and reads vertices and loop triangles
with ``foreach_get`` into numpy. Meshes shared by several instances are read once.
"""

import numpy as np

from ..core.geometry import MaterialInfo, ObjectInfo, concatenate
from .materials import material_info
from .labels import object_label
from .sensor import is_lidar

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def is_rls_helper(obj):
    """LiDAR objects, previews and regions of interest are never scanned."""
    return bool(obj.get("rls_preview") or obj.get("rls_infralob") or is_lidar(obj))


def _bounds_distance(matrix, bound_box, centre):
    corners = np.array([tuple(c) for c in bound_box], dtype=np.float64)
    m = np.array(matrix, dtype=np.float64)
    w = corners @ m[:3, :3].T + m[:3, 3]
    gap = np.maximum(np.maximum(w.min(0) - centre, centre - w.max(0)), 0.0)
    return float(np.sqrt(gap @ gap))


def _read_mesh(obj_eval):
    """(local vertices float64, triangles int64, material index int32) of an evaluated object."""
    mesh = obj_eval.to_mesh()
    try:
        mesh.calc_loop_triangles()
        nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
        co = np.empty(nv * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        tri = np.empty(nt * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
        mat = np.empty(nt, dtype=np.int32)
        mesh.loop_triangles.foreach_get("material_index", mat)
        return co.reshape(-1, 3).astype(np.float64), tri.reshape(-1, 3).astype(np.int64), mat
    finally:
        obj_eval.to_mesh_clear()


def extract_geometry(depsgraph, centre=None, max_range=None, exclude=()):
    """World-space triangles of everything visible to render in ``depsgraph``.

    centre, max_range   when given, objects whose world bounds are farther than
                        max_range from centre are not read at all
    exclude             names of original objects to leave out
    Returns (SceneGeometry, stats dict).
    """
    centre = None if centre is None else np.asarray(centre, dtype=np.float64)
    objects, materials, mat_index = [], [MaterialInfo("default")], {}
    parts, cache, instance_keys = [], {}, []
    stats = {"objects": 0, "culled_by_range": 0, "hidden": 0}
    for inst in depsgraph.object_instances:
        ob = inst.object
        orig = ob.original
        if ob.type not in GEOMETRY_TYPES or orig.name in exclude or is_rls_helper(orig):
            continue
        if orig.hide_render:
            stats["hidden"] += 1
            continue
        mw = inst.matrix_world
        if centre is not None and max_range is not None:
            if _bounds_distance(mw, ob.bound_box, centre) > max_range:
                stats["culled_by_range"] += 1
                continue
        key = (orig.name, ob.type)
        if key not in cache:
            cache[key] = _read_mesh(ob)
        co, tri, mat = cache[key]
        if len(tri) == 0:
            continue
        m = np.array(mw, dtype=np.float64)
        world = co @ m[:3, :3].T + m[:3, 3]
        slots = [s.material for s in ob.material_slots] or [None]
        local_to_global = np.zeros(len(slots), dtype=np.int32)
        for i, mt in enumerate(slots):
            if mt is None:
                continue
            if mt.name not in mat_index:
                mat_index[mt.name] = len(materials)
                materials.append(material_info(mt))
            local_to_global[i] = mat_index[mt.name]
        mat_g = local_to_global[np.clip(mat, 0, len(slots) - 1)]
        parent = inst.parent.original if inst.is_instance and inst.parent else None
        name = orig.name if parent is None else f"{parent.name}/{orig.name}#{inst.random_id}"
        objects.append((name, object_label(orig, parent)))
        parts.append((world, tri, np.full(len(tri), len(objects) - 1, np.int32), mat_g))
        stats["objects"] += 1
    # Stable instance ids: 1..K in name order, independent of depsgraph order.
    order = {n: i + 1 for i, n in enumerate(sorted(n for n, _ in objects))}
    infos = [ObjectInfo(n, lab, order[n]) for n, lab in objects]
    return concatenate(parts, infos, materials), stats
