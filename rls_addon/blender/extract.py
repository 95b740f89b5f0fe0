"""Scene extraction: evaluated depsgraph -> ``SceneGeometry`` in bulk.

Reads every evaluated object instance (modifiers, geometry nodes, collection
instances, curves and text as meshes), skips objects hidden from render and objects
whose bounds lie beyond the sensor's range, and reads vertices and loop triangles
with ``foreach_get`` into numpy. Meshes shared by several instances are read once.
Instances keep their local triangles and matrix, so the motion layer can treat moving
objects in their own frame; ``world_geometry`` joins any subset in world space with
one shared object table and material table.
"""

from dataclasses import dataclass

import numpy as np

from ..core.geometry import MaterialInfo, ObjectInfo, concatenate
from .labels import object_label
from .materials import material_info
from .sensor import is_lidar

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def is_rls_helper(obj):
    """LiDAR objects, previews and regions of interest are never scanned."""
    return bool(obj.get("rls_preview") or obj.get("rls_infralob") or is_lidar(obj)
                or obj.get("rls_fov"))


def _bounds_distance(matrix, bound_box, centre):
    corners = np.array([tuple(c) for c in bound_box], dtype=np.float64)
    m = np.array(matrix, dtype=np.float64)
    w = corners @ m[:3, :3].T + m[:3, 3]
    gap = np.maximum(np.maximum(w.min(0) - centre, centre - w.max(0)), 0.0)
    return float(np.sqrt(gap @ gap))


def read_mesh(obj_eval):
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


@dataclass
class Instance:
    """One evaluated object instance: its triangles in its own frame, and its matrix."""

    key: str              # unique name ('Object', or 'Instancer/Object#id' for instances)
    source: str           # name of the original object
    parent: str           # name of the instancing object ('' when not instanced)
    label: int
    vertices: np.ndarray  # local, float64
    triangles: np.ndarray
    materials: np.ndarray  # per triangle, index into the shared material table
    matrix: np.ndarray    # 4x4 world matrix
    slot_map: np.ndarray = None  # material slot -> index into the shared material table

    def material_indices(self, slot_indices):
        """Shared-table material index of per-triangle material slot indices."""
        return self.slot_map[np.clip(slot_indices, 0, len(self.slot_map) - 1)]


def _realizes_itself(inst):
    """Curves, text and surfaces evaluate to a mesh that the depsgraph lists as an
    instance of the object itself: that instance *is* the object."""
    return bool(inst.is_instance and inst.parent is not None
                and inst.parent.original.name == inst.object.original.name)


def instance_key(inst):
    """Stable name of a depsgraph instance."""
    orig = inst.object.original
    if inst.is_instance and inst.parent is not None and not _realizes_itself(inst):
        return f"{inst.parent.original.name}/{orig.name}#{inst.random_id}"
    return orig.name


def read_instances(depsgraph, centre=None, max_range=None, exclude=()):
    """Instances visible to render (see module doc). Returns (instances, material
    table, stats)."""
    centre = None if centre is None else np.asarray(centre, dtype=np.float64)
    materials, mat_index = [MaterialInfo("default")], {}
    cache, out = {}, []
    stats = {"objects": 0, "culled_by_range": 0, "hidden": 0}
    realized = {i.object.original.name for i in depsgraph.object_instances if _realizes_itself(i)}
    for inst in depsgraph.object_instances:
        ob = inst.object
        orig = ob.original
        if ob.type not in GEOMETRY_TYPES or orig.name in exclude or is_rls_helper(orig):
            continue
        if not inst.is_instance and orig.name in realized:
            continue  # read through its realized mesh instance instead
        if orig.hide_render:
            stats["hidden"] += 1
            continue
        mw = np.array(inst.matrix_world, dtype=np.float64)
        if centre is not None and max_range is not None:
            if _bounds_distance(mw, ob.bound_box, centre) > max_range:
                stats["culled_by_range"] += 1
                continue
        key = (orig.name, ob.type)
        if key not in cache:
            cache[key] = read_mesh(ob)
        co, tri, mat = cache[key]
        if len(tri) == 0:
            continue
        slots = [s.material for s in ob.material_slots] or [None]
        local_to_global = np.zeros(len(slots), dtype=np.int32)
        for i, mt in enumerate(slots):
            if mt is None:
                continue
            if mt.name not in mat_index:
                mat_index[mt.name] = len(materials)
                materials.append(material_info(mt))
            local_to_global[i] = mat_index[mt.name]
        parent = inst.parent.original if inst.is_instance and inst.parent else None
        if _realizes_itself(inst):
            parent = None
        item = Instance(instance_key(inst), orig.name, parent.name if parent else "",
                        object_label(orig, parent), co, tri, None, mw, local_to_global)
        item.materials = item.material_indices(mat)
        out.append(item)
        stats["objects"] += 1
    return out, materials, stats


def object_table(instances):
    """ObjectInfo per instance, with stable instance ids 1..K in key order."""
    order = {k: i + 1 for i, k in enumerate(sorted(i.key for i in instances))}
    return [ObjectInfo(i.key, i.label, order[i.key]) for i in instances]


def world_geometry(instances, objects, materials, select=None, matrices=None, local=False):
    """Join instances (all, or those whose index is in ``select``) into one geometry.

    matrices  optional {instance index: 4x4} replacing the stored matrices
    local     keep each instance's own coordinates (for a single moving object)
    Triangle object indices refer to ``objects`` (one entry per instance)."""
    parts = []
    for k, inst in enumerate(instances):
        if select is not None and k not in select:
            continue
        v = inst.vertices
        if not local:
            m = inst.matrix if matrices is None or k not in matrices else matrices[k]
            v = v @ m[:3, :3].T + m[:3, 3]
        parts.append((v, inst.triangles, np.full(len(inst.triangles), k, np.int32), inst.materials))
    return concatenate(parts, objects, materials)


def extract_geometry(depsgraph, centre=None, max_range=None, exclude=()):
    """World-space triangles of everything visible to render in ``depsgraph``.

    Returns (SceneGeometry, stats dict)."""
    instances, materials, stats = read_instances(depsgraph, centre, max_range, exclude)
    return world_geometry(instances, object_table(instances), materials), stats
