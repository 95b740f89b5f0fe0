"""Procedural street scenes for benchmarks, built with numpy as ``SceneGeometry``.

A straight 240 m street (road, sidewalks), rows of buildings with glazed windows,
parked cars (squashed ellipsoids), trees (cylinder trunk + sphere crown) and poles.
The layout is fixed by the seed; ``target_triangles`` only changes how finely every
surface is tessellated, so the series 10k .. 4M triangles shows the same street to
the sensor and differs only in triangle count.

``add_to_blender(geometry, scene)`` turns the result into Blender mesh objects (one per
scene object, in labelled collections) for the BVHTree pipeline on real ``bpy`` data.
"""

import numpy as np

from rls_addon.core.scene.geometry import MaterialInfo, ObjectInfo, SceneGeometry
from rls_addon.core.labels import NAME_TO_ID

MATERIALS = [MaterialInfo("default"), MaterialInfo("asphalt", 0.15),
             MaterialInfo("concrete", 0.45), MaterialInfo("facade", 0.5),
             MaterialInfo("glass", 0.2, glossy=True), MaterialInfo("paint", 0.6, glossy=True),
             MaterialInfo("bark", 0.3), MaterialInfo("leaves", 0.4), MaterialInfo("steel", 0.55)]
MAT = {m.name: i for i, m in enumerate(MATERIALS)}


def grid(p0, u, v, nu, nv):
    """A (nu x nv)-cell grid on the parallelogram p0 + s*u + t*v: (vertices, triangles)."""
    s = np.linspace(0.0, 1.0, nu + 1)
    t = np.linspace(0.0, 1.0, nv + 1)
    ss, tt = np.meshgrid(s, t, indexing="ij")
    verts = (np.asarray(p0, float) + ss.reshape(-1, 1) * np.asarray(u, float)
             + tt.reshape(-1, 1) * np.asarray(v, float))
    w = nv + 1
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * w + j).ravel()
    tris = np.concatenate([np.stack([a, a + w, a + w + 1], 1), np.stack([a, a + w + 1, a + 1], 1)])
    return verts, tris


def uv_sphere(rings, segments, radii=(1.0, 1.0, 1.0), centre=(0.0, 0.0, 0.0)):
    """Closed UV ellipsoid without degenerate triangles."""
    rings, segments = max(int(rings), 3), max(int(segments), 4)
    th = np.linspace(0, np.pi, rings + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t_, p_ = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t_) * np.cos(p_), np.sin(t_) * np.sin(p_), np.cos(t_)], -1)
    v = np.concatenate([[[0, 0, 1]], ring.reshape(-1, 3), [[0, 0, -1]]])
    v = v * np.asarray(radii, float) + np.asarray(centre, float)
    s = segments
    j = np.arange(s)
    top = np.stack([np.zeros(s, int), 1 + j, 1 + (j + 1) % s], 1)
    i, jj = np.meshgrid(np.arange(rings - 2), j, indexing="ij")
    a = (1 + i * s + jj).ravel()
    b = (1 + i * s + (jj + 1) % s).ravel()
    mid = np.concatenate([np.stack([a, a + s, b + s], 1), np.stack([a, b + s, b], 1)])
    base, last = 1 + (rings - 2) * s, len(v) - 1
    bottom = np.stack([base + j, np.full(s, last), base + (j + 1) % s], 1)
    return v, np.concatenate([top, mid, bottom])


def cylinder(segments, radius, height, centre, caps=True, rows=1):
    """Closed cylinder (side split into ``rows`` rows) standing on ``centre``."""
    segments = max(int(segments), 3)
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    z = np.linspace(0.0, height, rows + 1)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], 1)
    v = np.concatenate([np.column_stack([ring, np.full(segments, zz)]) for zz in z])
    v = v + np.asarray(centre, float)
    s = segments
    i, j = np.meshgrid(np.arange(rows), np.arange(s), indexing="ij")
    p = (i * s + j).ravel()
    q = (i * s + (j + 1) % s).ravel()
    tris = [np.stack([p, q, q + s], 1), np.stack([p, q + s, p + s], 1)]
    if caps:
        c0, c1 = len(v), len(v) + 1
        v = np.concatenate([v, [np.asarray(centre, float)],
                            [np.asarray(centre, float) + (0, 0, height)]])
        jj = np.arange(s)
        tris.append(np.stack([np.full(s, c0), (jj + 1) % s, jj], 1))
        top = rows * s
        tris.append(np.stack([np.full(s, c1), top + jj, top + (jj + 1) % s], 1))
    return v, np.concatenate(tris)


def box(lo, hi, cuts=1):
    """Axis-aligned box, each face a cuts x cuts grid."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    dx, dy, dz = hi - lo
    faces = [
        (lo, (0, dy, 0), (dx, 0, 0)), ((lo[0], lo[1], hi[2]), (dx, 0, 0), (0, dy, 0)),
        (lo, (dx, 0, 0), (0, 0, dz)), ((hi[0], lo[1], lo[2]), (0, dy, 0), (0, 0, dz)),
        ((hi[0], hi[1], lo[2]), (-dx, 0, 0), (0, 0, dz)), ((lo[0], hi[1], lo[2]), (0, -dy, 0), (0, 0, dz)),
    ]
    parts = [grid(p, u, v, cuts, cuts) for p, u, v in faces]
    return _join(parts)


def _join(parts):
    verts, tris, off = [], [], 0
    for v, t in parts:
        verts.append(v)
        tris.append(t + off)
        off += len(v)
    return np.concatenate(verts), np.concatenate(tris)


def _facade(x0, x1, y, h, detail, rng, facing):
    """A building front wall at y with windows: a tessellated grid wall plus a pane per
    window, 0.15 m in front of the wall. ``facing`` (+1 or -1): the street lies towards
    -facing * y, and the faces' normals point there, as a modeller's would."""
    width = x1 - x0
    n_cols = max(1, int(width / 3.2))
    n_rows = max(1, int(h / 3.0))
    cuts = max(1, int(round(2 * detail)))
    wall = grid((x0, y, 0.0), (width, 0, 0), (0, 0, h), cuts * n_cols, cuts * n_rows)
    parts, glass = [wall], []
    depth = 0.15 * facing
    for c in range(n_cols):
        for r in range(n_rows):
            if rng.random() < 0.15:
                continue
            wx = x0 + (c + 0.25) * width / n_cols
            wz = (r + 0.3) * h / n_rows
            ww, wh = 0.5 * width / n_cols, 0.45 * h / n_rows
            glass.append(grid((wx, y - depth, wz), (ww, 0, 0), (0, 0, wh), cuts, cuts))
    wall, panes = _join(parts), (_join(glass) if glass else None)
    if facing < 0:  # a grid spanned by +x then +z faces -y: turn these to face +y
        wall = (wall[0], wall[1][:, ::-1])
        panes = panes if panes is None else (panes[0], panes[1][:, ::-1])
    return wall, panes


def street_geometry(target_triangles=1_000_000, seed=7):
    """A street of about ``target_triangles`` triangles (within a few per cent)."""
    probe = _street(1.0, seed).triangle_count
    detail = np.sqrt(target_triangles / probe)
    for _ in range(3):
        g = _street(detail, seed)
        ratio = target_triangles / g.triangle_count
        if abs(ratio - 1) < 0.03:
            break
        detail *= ratio ** 0.5
    return g


def _street(detail, seed):
    rng = np.random.default_rng(seed)
    parts = _Parts()
    add = parts.add

    d = detail
    n = max(1, int(round(16 * d)))
    add("Road", "road", "asphalt", grid((-120, -7, 0), (240, 0, 0), (0, 14, 0), 12 * n, n))
    add("Sidewalk N", "sidewalk", "concrete", box((-120, 7, 0), (120, 10, 0.15), max(1, int(4 * d))))
    add("Sidewalk S", "sidewalk", "concrete", box((-120, -10, 0), (120, -7, 0.15), max(1, int(4 * d))))
    add("Ground", "terrain", "concrete", grid((-160, -80, -0.02), (320, 0, 0), (0, 160, 0), 2 * n, n))
    k = 0
    for side, y0, facing in ((1, 11.0, 1), (-1, -11.0, -1)):
        x = -118.0
        while x < 112:
            w = rng.uniform(10, 22)
            h = rng.uniform(8, 30)
            dep = rng.uniform(8, 14)
            x1 = min(x + w, 118.0)
            ylo, yhi = (y0, y0 + dep) if side > 0 else (y0 - dep, y0)
            add(f"Building {k}", "building", "facade", box((x, ylo, 0), (x1, yhi, h), max(1, int(2 * d))))
            front = ylo if side > 0 else yhi
            wall, glass = _facade(x, x1, front - 0.01 * facing, h, d, rng, facing)
            add(f"Facade {k}", "building", "facade", wall)
            if glass is not None:
                add(f"Windows {k}", "glass", "glass", glass)
            k += 1
            x = x1 + rng.uniform(0.5, 3.0)
    for i in range(40):
        side = 1 if i % 2 else -1
        x = -110 + i * 5.5 + rng.uniform(-1, 1)
        y = side * rng.uniform(3.5, 5.5)
        rings = max(3, int(6 * d))
        add(f"Car {i}", "vehicle", "paint",
            uv_sphere(rings, 2 * rings, (2.2, 0.9, 0.7), (x, y, 0.75)))
    for i in range(30):
        side = 1 if i % 2 else -1
        x = -115 + i * 8 + rng.uniform(-1.5, 1.5)
        y = side * 8.5
        seg = max(4, int(8 * d))
        add(f"Trunk {i}", "vegetation", "bark", cylinder(seg, 0.18, 3.0, (x, y, 0.15), rows=max(1, int(d))))
        r = rng.uniform(1.8, 2.8)
        rings = max(3, int(10 * d))
        add(f"Crown {i}", "vegetation", "leaves", uv_sphere(rings, 2 * rings, (r, r, r * 0.9), (x, y, 3.0 + r * 0.8)))
    for i in range(12):
        side = 1 if i % 2 else -1
        x = -110 + i * 20.0
        add(f"Pole {i}", "pole", "steel",
            cylinder(max(4, int(8 * d)), 0.12, 7.0, (x, side * 7.6, 0.15), rows=max(1, int(d))))
    return parts.geometry()


class _Parts:
    """A bench scene's objects as they are added: ``add`` one (its triangles labelled and
    given a material), ``geometry`` joins them into one SceneGeometry."""

    def __init__(self):
        self.parts, self.objects = [], []

    def add(self, name, label, material, vt):
        v, t = vt
        self.objects.append(ObjectInfo(name, NAME_TO_ID[label], len(self.objects) + 1))
        self.parts.append((v, t, np.full(len(t), len(self.objects) - 1),
                           np.full(len(t), MAT[material])))

    def geometry(self):
        """One SceneGeometry, each part's triangles shifted past the vertices before it."""
        parts = self.parts
        offsets = np.cumsum([0] + [len(v) for v, _, _, _ in parts[:-1]])
        return SceneGeometry(np.concatenate([v for v, _, _, _ in parts]),
                             np.concatenate([t + off for (_, t, _, _), off in zip(parts, offsets)]),
                             np.concatenate([o for _, _, o, _ in parts]),
                             np.concatenate([m for _, _, _, m in parts]), self.objects,
                             list(MATERIALS))


def open_sky_geometry(seed=11):
    """A small open-sky scene: a 200 m ground plane (a 100 x 100 grid), a sphere of
    radius 3 m and 50 boxes up to 4 m tall scattered within 60 m. From a sensor 5 m up
    (``OPEN_SKY_POSE``) about half the rays of a spinning device go to the sky and miss,
    the case where a frame costs most beyond its cast (issue 18)."""
    rng = np.random.default_rng(seed)
    parts = _Parts()
    add = parts.add

    add("Ground", "road", "asphalt", grid((-100, -100, 0), (200, 0, 0), (0, 200, 0), 100, 100))
    add("Sphere", "static", "paint", uv_sphere(16, 32, (3.0, 3.0, 3.0), (12.0, 6.0, 3.0)))
    for i in range(50):
        r, a = rng.uniform(8, 60), rng.uniform(0, 2 * np.pi)
        c = np.array([r * np.cos(a), r * np.sin(a)])
        half = rng.uniform(0.4, 2.0, 2)
        h = rng.uniform(0.5, 4.0)
        add(f"Box {i}", "building", "concrete",
            box((*(c - half), 0.0), (*(c + half), h), 2))
    return parts.geometry()


OPEN_SKY_POSE = np.array([[1.0, 0, 0, 0.0], [0, 1, 0, 0.0], [0, 0, 1, 5.0], [0, 0, 0, 1]])
"""The open-sky scene's sensor: 5 m above the middle of the ground plane."""

SENSOR_POSE = np.array([[1.0, 0, 0, 0.0], [0, 1, 0, 0.0], [0, 0, 1, 2.0], [0, 0, 0, 1]])
"""A car-roof mount in the middle of the street, 2 m up, looking along +X."""


def add_to_blender(geometry, scene):
    """Create one mesh object per scene object (world coordinates baked into the mesh)."""
    import bpy

    colls = {}
    for i, info in enumerate(geometry.objects):
        sel = geometry.tri_object == i
        tris = geometry.triangles[sel]
        used, inv = np.unique(tris, return_inverse=True)
        v = geometry.vertices[used]
        t = inv.reshape(-1, 3)
        mesh = bpy.data.meshes.new(info.name)
        mesh.vertices.add(len(v))
        mesh.vertices.foreach_set("co", v.astype(np.float32).ravel())
        mesh.loops.add(t.size)
        mesh.loops.foreach_set("vertex_index", t.astype(np.int32).ravel())
        mesh.polygons.add(len(t))
        mesh.polygons.foreach_set("loop_start", np.arange(0, t.size, 3, dtype=np.int32))
        mesh.update()
        obj = bpy.data.objects.new(info.name, mesh)
        obj["rls_label"] = int(info.label)
        label = info.name.split(" ")[0]
        coll = colls.get(label)
        if coll is None:
            coll = colls[label] = bpy.data.collections.new(label)
            scene.collection.children.link(coll)
        coll.objects.link(obj)
    return colls
