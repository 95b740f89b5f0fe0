"""Scene geometry as the engine sees it: world-space triangles with per-triangle
object and material indices, plus the per-object and per-material facts effects need."""

import hashlib
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..native.vectors import triangle_bounds


@dataclass(frozen=True)
class ObjectInfo:
    name: str
    label: int = 0
    instance: int = 0


@dataclass(frozen=True)
class MaterialInfo:
    name: str
    reflectivity: float = 0.5
    glossy: bool = False
    ghost_ratio: float = 0.5


@dataclass
class SceneGeometry:
    """Triangles of a scene.

    vertices      (V, 3) float64 world coordinates
    triangles     (T, 3) int64 vertex indices
    tri_object    (T,)   int32 index into ``objects``
    tri_material  (T,)   int32 index into ``materials``
    """

    vertices: np.ndarray
    triangles: np.ndarray
    tri_object: np.ndarray
    tri_material: np.ndarray
    objects: list = field(default_factory=list)
    materials: list = field(default_factory=lambda: [MaterialInfo("default")])
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        self.vertices = np.asarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.triangles = np.asarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        t = self.triangles.shape[0]
        self.tri_object = np.asarray(self.tri_object, dtype=np.int32).reshape(-1)
        self.tri_material = np.asarray(self.tri_material, dtype=np.int32).reshape(-1)
        if self.tri_object.shape != (t,) or self.tri_material.shape != (t,):
            raise SceneError("tri_object and tri_material need one entry per triangle")
        if t and (self.triangles.min() < 0 or self.triangles.max() >= len(self.vertices)):
            raise SceneError("triangle vertex index out of range")
        if not self.materials:
            self.materials = [MaterialInfo("default")]

    @property
    def triangle_count(self):
        return int(self.triangles.shape[0])

    def subset(self, keep):
        """A new geometry holding only the triangles where boolean ``keep`` is true
        (vertices are compacted)."""
        tris = self.triangles[keep]
        used, inverse = np.unique(tris, return_inverse=True)
        return SceneGeometry(
            self.vertices[used],
            inverse.reshape(-1, 3),
            self.tri_object[keep],
            self.tri_material[keep],
            self.objects,
            self.materials,
        )

    def object_field(self, name):
        """A per-object array of an ``ObjectInfo`` field ('label', 'instance'; uint32),
        computed once; one zero entry when there are no objects."""
        key = ("object", name)
        got = self._cache.get(key)
        if got is None:
            got = self._cache[key] = np.array(
                [getattr(o, name) for o in self.objects] or [0], np.uint32)
        return got

    def material_field(self, name):
        """A per-material array of a ``MaterialInfo`` field, computed once."""
        key = ("material", name)
        got = self._cache.get(key)
        if got is None:
            got = self._cache[key] = np.array([getattr(m, name) for m in self.materials])
        return got

    def surface_ids(self):
        """(T, 2) int32 rows (object index, material index), computed once: one gather
        at the hit triangles gives both, and every field then comes from the small
        per-object and per-material tables."""
        got = self._cache.get("surface_ids")
        if got is None:
            got = np.empty((self.triangle_count, 2), np.int32)
            got[:, 0] = self.tri_object if len(self.objects) else 0
            got[:, 1] = self.tri_material
            self._cache["surface_ids"] = got
        return got

    def per_triangle(self, name):
        """A per-triangle array of a material field ('reflectivity', 'glossy',
        'ghost_ratio') or an object field ('label', 'instance'), computed once."""
        got = self._cache.get(name)
        if got is None:
            if name in ("label", "instance"):
                got = self.object_field(name)[self.tri_object if len(self.objects) else
                                              np.zeros(self.triangle_count, np.int32)]
            else:
                got = self.material_field(name)[self.tri_material]
            self._cache[name] = got
        return got

    def fingerprint(self):
        """A digest of the triangles, their objects and materials: equal digests mean
        a built ray-casting structure can be reused."""
        h = hashlib.blake2b(digest_size=16)
        for a in (self.vertices, self.triangles, self.tri_object, self.tri_material):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(repr((self.objects, self.materials)).encode("utf-8"))
        return h.hexdigest()

    def label_map(self):
        """{instance id: {"object": name, "label": id}} for every object."""
        return {o.instance: {"object": o.name, "label": o.label} for o in self.objects}


def empty_geometry():
    return SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), np.int64), [], [])


def concatenate(parts, objects, materials):
    """Join (vertices, triangles, tri_object, tri_material) tuples into one geometry."""
    if not parts:
        g = empty_geometry()
        g.objects, g.materials = list(objects), list(materials) or g.materials
        return g
    verts, tris, objs, mats = [], [], [], []
    offset = 0
    for v, t, o, m in parts:
        verts.append(v)
        tris.append(np.asarray(t, np.int64) + offset)
        objs.append(o)
        mats.append(m)
        offset += len(v)
    return SceneGeometry(np.concatenate(verts), np.concatenate(tris), np.concatenate(objs),
                         np.concatenate(mats), list(objects), list(materials))


def triangle_normals(vertices, triangles):
    """Unnormalised normals (cross products) and areas of triangles, float64."""
    v0 = vertices[triangles[:, 0]]
    n = np.cross(vertices[triangles[:, 1]] - v0, vertices[triangles[:, 2]] - v0)
    return n, 0.5 * np.linalg.norm(n, axis=1)


def finite_triangles(vertices, triangles):
    """(T,) bool: whether each triangle's three vertices have finite coordinates."""
    ok = np.isfinite(vertices).all(axis=1)
    return ok[triangles].all(axis=1) if len(triangles) else np.ones(0, bool)


def nonfinite_warning(skipped):
    """The one warning for the triangles skipped for NaN or infinite coordinates:
    ``skipped`` {object name: triangles skipped}."""
    names = ", ".join(f"'{name}' ({n})" for name, n in sorted(skipped.items()))
    return (f"skipped {sum(skipped.values())} triangle(s) with NaN or infinite vertex "
            f"coordinates: {names}; fix those objects' vertices or transforms to scan them")


def clean_for_casting(geometry, centre, max_range, min_area=1e-12):
    """Sensor-centred triangles for ray casting.

    Returns (vertices - centre, triangles, kept_indices, warnings): triangles with a NaN
    or infinite vertex coordinate (one warning naming their objects), degenerate
    (zero-area) triangles and triangles wholly beyond ``max_range`` of ``centre`` are
    dropped; coordinates are shifted before any float32 conversion so that scenes far
    from the origin keep their precision.
    """
    warnings = []
    c = np.asarray(centre, dtype=np.float64)
    if geometry.triangle_count == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), warnings
    local = geometry.vertices - c
    tris = geometry.triangles
    finite = finite_triangles(local, tris)
    if not finite.all():
        objects = geometry.objects
        counts = np.bincount(geometry.tri_object[~finite])
        warnings.append(nonfinite_warning({
            (objects[k].name if k < len(objects) else f"object {k}"): int(n)
            for k, n in enumerate(counts) if n}))
    # the skipped triangles' arithmetic gives NaN: they are dropped, quietly
    with np.errstate(invalid="ignore", over="ignore"):
        _, area = triangle_normals(local, tris)
        good = area > min_area
        n_bad = int(np.count_nonzero(finite & ~good))
        good &= finite
        if n_bad:
            warnings.append(f"skipped {n_bad} degenerate (zero-area) triangle(s)")
        # Distance from the sensor to each triangle's bounding box.
        lo, hi = triangle_bounds(local, tris)
        gap = np.maximum(np.maximum(lo, -hi), 0.0)
        near = np.einsum("ij,ij->i", gap, gap) <= float(max_range) ** 2
    keep = np.nonzero(good & near)[0]
    return local, tris[keep], keep, warnings


def hit_body(tri):
    """Body 0 where ``tri`` is a hit (>= 0), -1 where a miss (< 0): the sign bit,
    shifted down (a tenth of np.where's time)."""
    return np.right_shift(np.asarray(tri, np.int64), 63)


def pair_rows(table, rows):
    """``table.take(rows, axis=0)`` for a C-contiguous (T, 2) int32 table, as one
    gather of 8-byte rows: numpy's take slows threefold on negative rows (misses), and
    fancy indexing of a 1-D array does not."""
    if not (table.flags.c_contiguous and table.dtype == np.int32):
        return table.take(rows, axis=0)
    return table.view(np.int64).reshape(-1)[rows].view(np.int32).reshape(-1, 2)
