"""Scene extraction: evaluated depsgraph -> ``SceneGeometry`` in bulk.

Reads every evaluated object instance (modifiers, geometry nodes, collection
instances, curves and text as meshes), skips objects hidden from render and objects
whose bounds lie beyond the sensor's range, and reads vertices and triangles with
``foreach_get`` into numpy: positions, corners and face materials from Blender's
attribute arrays (copied at memory speed); triangles from Blender's own triangulation
only where a mesh has faces of four or more corners (``loop_triangles`` comes one
triangle at a time, ~0.15 us each). Meshes shared by several instances are read once,
and a ``MeshReader`` (one per scan session) reads an unchanged mesh once over frames.
Instances keep their local triangles and matrix, so the motion layer can treat moving
objects in their own frame; ``world_geometry`` joins any subset in world space with
one shared object table and material table.

Objects and materials are told apart by name (an instance's key, its mesh read once,
its motion and label; a material's reflectivity). Names are unique within one file,
but not across the libraries a scene links from: two objects (or materials) of the
same name, one linked, are refused with the names to change, never read as one. The
depsgraph read is the viewport's: an object hidden in the viewport but not from render
is not in it, so it is not scanned, and the read names it for the scan to say so, as it
names modifiers a render applies otherwise. Blender units are read as metres: a scene
whose Unit Scale is not 1 (one unit another length) is refused, never scanned at the
wrong size. These rules live in ``read_rules``; what a read made of objects that
cannot change is kept between frames of a file nobody edits (``still_reads``).
"""

import dataclasses
import itertools

import numpy as np

from ..core.errors import SceneError
from ..core.scene.geometry import MaterialInfo
from ..core.scene.instances import Instance, object_table, world_geometry
from .labels import object_label
from .materials import material_info
from .read_rules import (GEOMETRY_TYPES, Named, hidden_in_viewport, in_metres, is_rls_helper,
                         one_per_name, render_differs, shown_itself_in_render)
from .still_reads import StillEntry


def _corners(bound_box):
    """(8, 3) float64 corners of an object's local bounds (Blender's floats in one call
    where it has ``foreach_get``)."""
    if hasattr(bound_box, "foreach_get"):
        flat = np.empty(24, np.float32)
        bound_box.foreach_get(flat)
        return flat.reshape(8, 3).astype(np.float64)
    return np.array([tuple(c) for c in bound_box], dtype=np.float64)


def _bounds_distance(matrix, bound_box, centre):
    """Distance from ``centre`` to an object's bounds in the world; 0 when they are not
    finite (a NaN or infinite vertex or matrix): the object is read, and the core skips
    its broken triangles with a warning naming it. One object's: the reference of
    ``_bounds_distances``."""
    corners = _corners(bound_box)
    m = np.array(matrix, dtype=np.float64)
    if not (np.isfinite(corners).all() and np.isfinite(m).all()):
        return 0.0
    w = corners @ m[:3, :3].T + m[:3, 3]
    gap = np.maximum(np.maximum(w.min(0) - centre, centre - w.max(0)), 0.0)
    return float(np.sqrt(gap[0] * gap[0] + gap[1] * gap[1] + gap[2] * gap[2]))


def _bounds_distances(matrices, corners, centre):
    """``_bounds_distance`` of N objects at once ((N, 4, 4) matrices, (N, 8, 3) local
    corners): the same products and sums, element for element (tested)."""
    out = np.zeros(len(matrices))
    ok = np.isfinite(corners).all(axis=(1, 2)) & np.isfinite(matrices).all(axis=(1, 2))
    m = matrices[ok]
    w = corners[ok] @ np.swapaxes(m[:, :3, :3], 1, 2) + m[:, None, :3, 3]
    gap = np.maximum(np.maximum(w.min(axis=1) - centre, centre - w.max(axis=1)), 0.0)
    # the squares summed in order, as one object's are: a dot product or einsum may
    # fuse or reorder them (1 ulp apart on some machines' OpenBLAS and numpy builds)
    out[ok] = np.sqrt(gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] + gap[:, 2] * gap[:, 2])
    return out


def read_mesh(obj_eval):
    """(local vertices float64, triangles int64, material index int32) of an evaluated object."""
    return _read(obj_eval)[0]


def read_positions(obj_eval):
    """Local vertices (float64) of an evaluated object, without its triangles."""
    mesh = obj_eval.to_mesh()
    try:
        got = _attribute_arrays(mesh)
        co = got[0] if got is not None else _by_item(mesh.vertices, "co", 3, np.float32)
        return co.reshape(-1, 3).astype(np.float64)
    finally:
        obj_eval.to_mesh_clear()


class MeshReader:
    """Reads evaluated meshes for a scan session, keeping each object's last read: a
    mesh whose positions, corners and face materials are the same as when it was last
    read is given back as read then, without reading its triangles again. Every new
    read gets a new id, kept while the read is reused (equal ids: equal meshes)."""

    KEEP_SCANS = 64  # an object not read in this many scans (sensors x frames) is dropped

    def __init__(self, fixed=None):
        self._known = {}  # key -> (id, check arrays, (vertices, triangles, materials), scan)
        self._ids = itertools.count(1)
        self._scans = 0
        self.reads = 0  # meshes read in full (not reused)
        # fixed(original object): its evaluated mesh cannot change while the file is
        # not edited (then a mesh read once is given back without evaluating it again)
        self.fixed = fixed

    def read(self, obj_eval, key):
        """(vertices, triangles, material index, id) of the evaluated object ``key``."""
        known = self._known.get(key)
        if known is not None and self.fixed is not None and self.fixed(obj_eval.original):
            self._known[key] = known[:3] + (self._scans,)
            return known[2] + (known[0],)
        mesh, check = _read(obj_eval, known[1] if known else None)
        if mesh is None:  # unchanged since that read
            entry = known[:3]
        else:
            entry = (next(self._ids), check, mesh)
            self.reads += 1
        self._known[key] = entry + (self._scans,)
        return entry[2] + (entry[0],)

    def scan_done(self):
        """End of one scan's reads: objects unread for ``KEEP_SCANS`` scans (deleted,
        hidden, out of every sensor's range) are forgotten."""
        self._scans += 1
        old = self._scans - self.KEEP_SCANS
        for key in [k for k, e in self._known.items() if e[3] < old]:
            del self._known[key]


def _by_item(collection, prop, width, dtype):
    out = np.empty(len(collection) * width, dtype=dtype)
    collection.foreach_get(prop, out)
    return out


def _attribute_arrays(mesh):
    """(positions float32, corner vertices int32, face materials int32) from the mesh's
    attribute arrays, or None where this Blender does not have them."""
    attrs = mesh.attributes
    pos, corners = attrs.get("position"), attrs.get(".corner_vert")
    if pos is None or corners is None:
        return None
    co = _by_item(pos.data, "vector", 3, np.float32)
    cv = _by_item(corners.data, "value", 1, np.int32)
    mi = attrs.get("material_index")
    fm = _by_item(mi.data, "value", 1, np.int32) if mi is not None and mi.domain == "FACE" \
        else np.zeros(len(mesh.polygons), np.int32)
    return co, cv, fm


def _read(obj_eval, known=None):
    """((vertices, triangles, material index) or None, check arrays) of an evaluated
    object; None (with ``known``) when the check arrays equal ``known``."""
    mesh = obj_eval.to_mesh()
    try:
        got = _attribute_arrays(mesh)
        if got is None:  # an older Blender: every array item by item
            mesh.calc_loop_triangles()
            co = _by_item(mesh.vertices, "co", 3, np.float32)
            tri = _by_item(mesh.loop_triangles, "vertices", 3, np.int32)
            mat = _by_item(mesh.loop_triangles, "material_index", 1, np.int32)
            check = None
        else:
            co, cv, fm = got
            triangles_only = len(cv) == 3 * len(fm)  # then the faces are the triangulation
            if triangles_only:
                check = (co, cv, fm)
            else:
                # Which face each of Blender's triangles is in: with the corners, how the
                # corners group into faces, which the check must hold too.
                mesh.calc_loop_triangles()
                face = _by_item(mesh.loop_triangle_polygons, "value", 1, np.int32)
                check = (co, cv, fm, face)
            if known is not None and _same(known, check):
                return None, check
            if triangles_only:
                tri, mat = cv, fm
            else:
                tri, mat = _by_item(mesh.loop_triangles, "vertices", 3, np.int32), fm[face]
        return ((co.reshape(-1, 3).astype(np.float64), tri.reshape(-1, 3).astype(np.int64),
                 mat), check)
    finally:
        obj_eval.to_mesh_clear()


def _same(a, b):
    return a is not None and b is not None and len(a) == len(b) and all(
        np.array_equal(x, y) for x, y in zip(a, b))


def _realizes_itself(inst):
    """Curves, text and surfaces evaluate to a mesh that the depsgraph lists as an
    instance of the object itself: that instance *is* the object."""
    return bool(inst.is_instance and inst.parent is not None
                and inst.parent.original.name == inst.object.original.name)


def _realized(depsgraph, exclude=()):
    """Names of the objects the depsgraph lists as an instance of themselves: curves,
    text and surfaces evaluated to a mesh (``_realizes_itself``), read through that
    instance. Geometry nodes that make instances of geometry they generate (Instance on
    Points of a generated mesh, or of an object's geometry) list such instances too,
    one per instance and on a mesh object, with no name or mesh of their own to tell
    them apart: they would be scanned as one another, or not at all, so a
    ``SceneError`` says how to scan the object instead (not for objects left out of
    the read: ``exclude``, hidden from render, and what RLS draws, such as a preview's
    points)."""
    count, types = {}, {}
    for inst in depsgraph.object_instances:
        if _realizes_itself(inst):
            orig = inst.object.original
            name = orig.name
            if name in exclude or orig.hide_render or is_rls_helper(orig):
                continue
            count[name] = count.get(name, 0) + 1
            types[name] = orig.type
    for name, n in count.items():
        if n > 1 or types[name] == "MESH":
            raise SceneError(
                f"object '{name}': its geometry nodes make instances of geometry they "
                "generate (an Instance on Points of a generated mesh, or of an object's "
                "geometry), which RLS cannot tell apart yet and would scan wrongly; add a "
                "Realize Instances node before its Group Output, or instance objects of a "
                "collection instead")
    return set(count)


def instance_key(inst):
    """Stable name of a depsgraph instance."""
    orig = inst.object.original
    if inst.is_instance and inst.parent is not None and not _realizes_itself(inst):
        return f"{inst.parent.original.name}/{orig.name}#{inst.random_id}"
    return orig.name


def read_instances(depsgraph, centre=None, max_range=None, exclude=(), reader=None,
                   labels=None, still=None):
    """Instances visible to render (see module doc). Returns (instances, material
    table, stats). ``reader``: a scan session's ``MeshReader`` (meshes unchanged since
    its last frame are not read again, and instances carry its mesh ids). ``labels``: a
    dict kept by a source whose file nobody edits, {(object, instancer): label id}, so
    each object's label is looked up once (its collections are walked for it).
    ``still``: (names of objects that cannot change, {name: ``StillEntry``} of the reads
    with this centre, range and exclusions), for a source whose file nobody edits
    (``still_reads``): what an earlier read made of such an object is given back, the
    others read; the same read, object for object.

    Two walks over the instances: the first finds those to read and their bounds (every
    one's distance from ``centre`` in one product, ``_bounds_distances``), the second
    reads them (an instance is valid only while the walk is at it)."""
    in_metres(depsgraph.scene)
    centre = None if centre is None else np.asarray(centre, dtype=np.float64)
    materials, mat_index = [MaterialInfo("default")], {}
    cache, out = {}, []
    stats = {"objects": 0, "culled_by_range": 0, "hidden": 0}
    realized = _realized(depsgraph, exclude)
    wanted, matrices, corners = [], [], []
    names, material_names = {}, {}  # name -> full name (with its library), of those seen
    still_names, entries = still if still is not None else ((), None)
    kept, fresh = {}, {}  # walk position -> StillEntry given back, or being made
    kept_far = 0
    viewport_only = []  # "'object' (modifier)" set otherwise for render than viewport
    looked_at = set()   # objects whose modifiers were looked at
    for n, inst in enumerate(depsgraph.object_instances):
        ob = inst.object
        orig = ob.original
        entry = None
        if not inst.is_instance and orig.name in still_names:
            entry = entries.get(orig.name)
            if entry is not None:  # read before, and cannot have changed
                one_per_name(names, Named(orig.name, entry.full_name), "objects")
                kept[n] = entry
                stats["hidden"] += entry.kind == "hidden"
                kept_far += entry.kind == "far"
                continue
            entry = fresh[n] = entries[orig.name] = StillEntry(orig.name_full)
        if ob.type not in GEOMETRY_TYPES:
            continue
        # every geometry object, read or not (a hidden or distant one's matrix would be
        # taken for its namesake's in a sweep), and the instancer
        one_per_name(names, orig, "objects")
        if inst.is_instance and inst.parent is not None:
            one_per_name(names, inst.parent.original, "objects")
        if orig.name in exclude or is_rls_helper(orig):
            continue
        if not inst.is_instance and orig.name in realized:
            continue  # read through its realized mesh instance instead
        if orig.hide_render or (not inst.is_instance and not shown_itself_in_render(orig)):
            stats["hidden"] += 1
            if entry is not None:
                entry.kind = "hidden"
            continue
        if len(orig.modifiers) and orig.name not in looked_at:
            looked_at.add(orig.name)
            viewport_only += [f"'{orig.name}' ({mod})" for mod in render_differs(orig)]
        wanted.append(n)
        matrices.append(np.array(inst.matrix_world, dtype=np.float64))
        if centre is not None and max_range is not None:
            corners.append(_corners(ob.bound_box))
    stats["hidden_in_viewport"] = hidden_in_viewport(depsgraph, set(names.values()))
    stats["viewport_modifiers"] = viewport_only
    if corners:
        near = _bounds_distances(np.array(matrices), np.array(corners), centre) <= max_range
        stats["culled_by_range"] = int(len(near) - np.count_nonzero(near)) + kept_far
        keep = {n: mw for n, mw, ok in zip(wanted, matrices, near) if ok}
        for n, ok in zip(wanted, near):
            if not ok and n in fresh:
                fresh[n].kind = "far"
    else:
        stats["culled_by_range"] += kept_far
        keep = dict(zip(wanted, matrices))
    for n, inst in enumerate(depsgraph.object_instances):
        entry = kept.get(n)
        if entry is not None:
            if entry.kind == "read":
                out.append(_kept_instance(entry, materials, mat_index, material_names))
                stats["objects"] += 1
            continue
        mw = keep.get(n)
        if mw is None:
            continue
        ob = inst.object
        orig = ob.original
        key = (orig.name, ob.type)
        if key not in cache:
            cache[key] = reader.read(ob, key) if reader is not None else read_mesh(ob) + (0,)
        co, tri, mat, mesh_id = cache[key]
        entry = fresh.get(n)
        if len(tri) == 0:
            if entry is not None:
                entry.kind = "empty"
            continue
        slots = [s.material for s in ob.material_slots] or [None]
        local_to_global = _slot_map(slots, material_info, materials, mat_index, material_names)
        parent = inst.parent.original if inst.is_instance and inst.parent else None
        if _realizes_itself(inst):
            parent = None
        label = _label(orig, parent, labels)
        item = Instance(instance_key(inst), orig.name, parent.name if parent else "",
                        label, co, tri, None, mw, local_to_global, mesh_id)
        item.materials = item.material_indices(mat)
        out.append(item)
        stats["objects"] += 1
        if entry is not None:
            entry.kind, entry.instance, entry.slots = "read", item, mat
            entry.slot_materials = [None if mt is None else Named(mt.name, mt.name_full)
                                    for mt in slots]
            entry.infos = {mt.name: materials[mat_index[mt.name]] for mt in slots
                           if mt is not None}
    if reader is not None:
        reader.scan_done()
    return out, materials, stats


def _slot_map(slots, info_of, materials, mat_index, material_names):
    """An object's material slots (materials, or their ``Named`` names; None: empty) as
    indices into the read's shared table: each material noted once per name
    (``one_per_name``) and added at its first use, its ``info_of(material)``."""
    local_to_global = np.zeros(len(slots), dtype=np.int32)
    for i, mt in enumerate(slots):
        if mt is None:
            continue
        one_per_name(material_names, mt, "materials")
        if mt.name not in mat_index:
            mat_index[mt.name] = len(materials)
            materials.append(info_of(mt))
        local_to_global[i] = mat_index[mt.name]
    return local_to_global


def _kept_instance(entry, materials, mat_index, material_names):
    """A still object's instance from an earlier read (``StillEntry``), its materials
    noted and added to this read's table as reading it again would (``_slot_map``);
    the same record when they land where they did then, else one with its slots mapped
    anew."""
    local_to_global = _slot_map(entry.slot_materials, lambda named: entry.infos[named.name],
                                materials, mat_index, material_names)
    inst = entry.instance
    if np.array_equal(local_to_global, inst.slot_map):
        return inst
    item = dataclasses.replace(inst, slot_map=local_to_global)
    item.materials = item.material_indices(entry.slots)
    return item


def _label(orig, parent, labels):
    """``object_label(orig, parent)``, looked up once per pair in ``labels`` (a dict, or
    None: every time)."""
    if labels is None:
        return object_label(orig, parent)
    key = (orig.name, parent.name if parent is not None else None)
    got = labels.get(key)
    if got is None:
        got = labels[key] = object_label(orig, parent)
    return got


def extract_geometry(depsgraph, centre=None, max_range=None, exclude=()):
    """World-space triangles of everything visible to render in ``depsgraph``.

    Returns (SceneGeometry, stats dict)."""
    instances, materials, stats = read_instances(depsgraph, centre, max_range, exclude)
    return world_geometry(instances, object_table(instances), materials), stats
