"""Small analytic scenes for core tests (numpy only)."""

import numpy as np

from rls_addon.core.scene.geometry import MaterialInfo, ObjectInfo, SceneGeometry

BOX_TRIS = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                     [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box_vertices(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                     [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)


def box_geometry(lo, hi, label=0, instance=1, name="box", material=None):
    mats = [material or MaterialInfo("grey", 0.5)]
    return SceneGeometry(box_vertices(lo, hi), BOX_TRIS, np.zeros(12, int), np.zeros(12, int),
                         [ObjectInfo(name, label, instance)], mats)


def box_sdf(p, centre, half):
    """Signed distance of points p (N,3) to axis-aligned boxes (centre (N,3) or (3,))."""
    q = np.abs(p - centre) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def merge(*geoms):
    """Join geometries whose object/material tables are independent."""
    verts, tris, tobj, tmat, objs, mats = [], [], [], [], [], []
    vo = 0
    for g in geoms:
        verts.append(g.vertices)
        tris.append(g.triangles + vo)
        tobj.append(g.tri_object + len(objs))
        tmat.append(g.tri_material + len(mats))
        vo += len(g.vertices)
        objs += g.objects
        mats += g.materials
    return SceneGeometry(np.concatenate(verts), np.concatenate(tris), np.concatenate(tobj),
                         np.concatenate(tmat), objs, mats)


def open_sky(boxes=20, seed=2):
    """A 100 m ground plane (a grid), a few boxes up to 3 m tall and a glossy one."""
    rng = np.random.default_rng(seed)
    n = 40
    s = np.linspace(-50, 50, n + 1)
    gx, gy = np.meshgrid(s, s, indexing="ij")
    verts = [np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], 1)]
    k = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None]
    k = k.ravel()
    tris = [np.concatenate([np.stack([k, k + n + 1, k + 1], 1),
                            np.stack([k + 1, k + n + 1, k + n + 2], 1)])]
    objs, mats = [np.zeros(len(tris[0]), np.int64)], [np.zeros(len(tris[0]), np.int64)]
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                     [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    off = len(verts[0])
    for i in range(boxes):
        lo = np.r_[rng.uniform(-30, 30, 2), 0.0]
        size = np.r_[rng.uniform(0.5, 3, 2), rng.uniform(0.5, 3.0)]
        verts.append(lo + cube * size)
        tris.append(faces + off)
        objs.append(np.full(12, i + 1))
        mats.append(np.full(12, 2 if i == 0 else 1))
        off += 8
    objects = [ObjectInfo("Ground", 1, 1)] + [ObjectInfo(f"Box {i}", 3, i + 2)
                                              for i in range(boxes)]
    return SceneGeometry(np.concatenate(verts), np.concatenate(tris), np.concatenate(objs),
                         np.concatenate(mats), objects,
                         [MaterialInfo("asphalt", 0.2), MaterialInfo("concrete", 0.5),
                          MaterialInfo("glass", 0.3, glossy=True)])


def rays_entering_boxes(origin, directions, lo, hi, max_dist=np.inf, chunk=8192):
    """(N,) bool: the ray from ``origin`` enters (or starts in) one of the boxes
    [lo, hi] within ``max_dist``: the exact slab test over every (ray, box) pair, a
    ``chunk`` of rays at a time so the (rays, boxes, 3) arrays stay small."""
    out = np.zeros(len(directions), bool)
    for s in range(0, len(directions), chunk):
        d = directions[s:s + chunk]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (lo[None] - origin) * inv[:, None]
            t2 = (hi[None] - origin) * inv[:, None]
            near = np.nanmax(np.minimum(t1, t2), axis=2)
            far = np.nanmin(np.maximum(t1, t2), axis=2)
        out[s:s + chunk] = ((near <= far) & (far >= 0) & (near <= max_dist)).any(axis=1)
    return out
