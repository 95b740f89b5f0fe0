"""A scene as a scene source hands it over: object instances, each with its triangles in
its own frame and its world matrix, sharing one material table. The core joins any
subset of them in world space (``world_geometry``), or keeps one in its own frame for
a moving body."""

import dataclasses
import hashlib
import math
from dataclasses import dataclass

import numpy as np

from .geometry import ObjectInfo, concatenate


@dataclass
class Instance:
    """One object instance: its triangles in its own frame, and its matrix."""

    key: str              # unique name ('Object', or 'Instancer/Object#id' for instances)
    source: str           # name of the original object
    parent: str           # name of the instancing object ('' when not instanced)
    label: int
    vertices: np.ndarray  # local, float64
    triangles: np.ndarray
    materials: np.ndarray  # per triangle, index into the shared material table
    matrix: np.ndarray    # 4x4 world matrix
    slot_map: np.ndarray = None  # material slot -> index into the shared material table
    mesh_id: int = 0  # the source's id of the mesh read (equal ids: equal meshes; 0: none)

    def material_indices(self, slot_indices):
        """Shared-table material index of per-triangle material slot indices."""
        return self.slot_map[np.clip(slot_indices, 0, len(self.slot_map) - 1)]


def instance_id(key):
    """The stable instance id of an object: the same in every sensor, frame, file and
    run, derived from the object's key (its name, or 'Instancer/Object#n' for a
    collection instance) by a 31-bit BLAKE2 hash, never 0 (0 is 'no object'). Two of
    a few thousand names share an id with a chance of about 1 in 1000; a run checks
    its id map and says so (``check_ids``)."""
    digest = hashlib.blake2b(str(key).encode("utf-8"), digest_size=4).digest()
    return (int.from_bytes(digest, "little") & 0x7FFFFFFF) or 1


def object_table(instances):
    """ObjectInfo per instance, with stable instance ids (``instance_id``)."""
    return [ObjectInfo(i.key, i.label, instance_id(i.key)) for i in instances]


def check_ids(id_map):
    """Warnings for instance ids shared by different objects in ``id_map`` ({id: set of
    object names})."""
    return [f"objects {', '.join(sorted(names))} share instance id {i}: rename one of them "
            "to tell their points apart" for i, names in sorted(id_map.items()) if len(names) > 1]


def without_nonfinite(instances, skipped):
    """``instances`` without their triangles that have a NaN or infinite vertex
    coordinate (all of an instance whose matrix is not finite), vertices compacted;
    each instance's count of skipped triangles is added to ``skipped`` ({key: count},
    for ``geometry.nonfinite_warning``). Instances with nothing to skip are kept as they
    are; instances left with no triangle are left out."""
    out = []
    with np.errstate(over="ignore", invalid="ignore"):  # numpy says nothing
        for inst in instances:
            _keep_finite(inst, out, skipped)
    return out


def _keep_finite(inst, out, skipped):
    """``without_nonfinite`` of one instance: appended to ``out`` as it is, cleaned, or
    not at all."""
    # A sum is finite only when every term is (a NaN or an infinity never cancels
    # out): one reduction each clears nearly every instance (an overflowing sum of
    # finite numbers is looked at row by row below, and kept as it is).
    if math.isfinite(float(inst.vertices.sum())) and math.isfinite(float(inst.matrix.sum())):
        out.append(inst)
        return
    ok = np.isfinite(inst.vertices).all(axis=1)
    if ok.all() and np.isfinite(inst.matrix).all():
        out.append(inst)
        return
    keep = ok[inst.triangles].all(axis=1) if np.isfinite(inst.matrix).all() \
        else np.zeros(len(inst.triangles), bool)
    skipped[inst.key] = skipped.get(inst.key, 0) + int(np.count_nonzero(~keep))
    if not keep.any():
        return
    used, inverse = np.unique(inst.triangles[keep], return_inverse=True)
    out.append(dataclasses.replace(inst, vertices=inst.vertices[used],
                                   triangles=inverse.reshape(-1, 3),
                                   materials=np.asarray(inst.materials)[keep]))


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


def bodies_key(instances, objects, materials, indices):
    """A key equal for equal moving bodies (the instances ``indices``, each in its own
    coordinates: ``world_geometry(..., select={k}, local=True)``), from what was read
    (no digest of the triangles): each one's index, mesh id and materials, and the
    object and material tables. None when a mesh has no id."""
    parts = []
    for k in indices:
        inst = instances[k]
        if not inst.mesh_id:
            return None
        parts.append((k, inst.key, inst.label, inst.mesh_id, inst.slot_map.tobytes()))
    return ("bodies", tuple(parts), repr((objects, materials)))


def static_key(instances, objects, materials, select):
    """A key equal for equal static geometry, from what was read (no digest of the
    triangles): each selected instance's mesh id, matrix, materials and label, and the
    object and material tables. None when a mesh has no id."""
    parts = []
    for k in sorted(select):
        inst = instances[k]
        if not inst.mesh_id:
            return None
        parts.append((inst.key, inst.label, inst.mesh_id, inst.matrix.tobytes(),
                      inst.slot_map.tobytes()))
    return ("instances", tuple(parts), repr((objects, materials)))
