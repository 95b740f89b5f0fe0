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
