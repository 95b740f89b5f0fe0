"""Shared helpers for backend parity tests: analytic scenes, ray sets and the
comparison rule (exact-range agreement everywhere, identical hit/miss away from edges)."""

import numpy as np

from rls_addon.core.world.bodies import PreparedScene
from rls_addon.core.scene.geometry import SceneGeometry


def geometry(vertices, triangles):
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    return SceneGeometry(np.asarray(vertices, np.float64), t, np.zeros(len(t)),
                         np.zeros(len(t)))


def grid_plane(size=40.0, z=-2.0, cuts=10, offset=(0.0, 0.0, 0.0)):
    xs = np.linspace(-size, size, cuts + 1)
    x, y = np.meshgrid(xs, xs)
    v = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], 1) + offset
    w = cuts + 1
    i, j = np.meshgrid(np.arange(cuts), np.arange(cuts))
    a = (j * w + i).ravel()
    t = np.concatenate([np.stack([a, a + 1, a + w + 1], 1), np.stack([a, a + w + 1, a + w], 1)])
    return geometry(v, t)


def box(lo=(-4.0, -3.0, -1.5), hi=(5.0, 3.5, 2.5)):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
         (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    quads = [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]
    t = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return geometry(v, t)


def uv_sphere(radius=3.0, rings=24, segments=48, centre=(0.0, 0.0, 0.0)):
    """Closed UV sphere: poles as single vertices, no degenerate triangles."""
    th = np.linspace(0, np.pi, rings + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t_, p_ = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t_) * np.cos(p_), np.sin(t_) * np.sin(p_), np.cos(t_)], -1)
    v = np.concatenate([[[0, 0, 1]], ring.reshape(-1, 3), [[0, 0, -1]]]) * radius + centre
    s = segments
    tris = []
    for j in range(s):
        tris.append((0, 1 + j, 1 + (j + 1) % s))
    for i in range(rings - 2):
        for j in range(s):
            a, b = 1 + i * s + j, 1 + i * s + (j + 1) % s
            tris += [(a, a + s, b + s), (a, b + s, b)]
    last = len(v) - 1
    base = 1 + (rings - 2) * s
    for j in range(s):
        tris.append((base + j, last, base + (j + 1) % s))
    return geometry(v, np.array(tris))


def random_directions(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def lidar_directions(channels=32, columns=360, fov=(-25.0, 15.0)):
    el = np.radians(np.linspace(fov[0], fov[1], channels))
    az = np.linspace(-np.pi, np.pi, columns, endpoint=False)
    a, e = np.meshgrid(az, el, indexing="ij")
    a, e = a.ravel(), e.ravel()
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], 1)


def edge_distance(scene, origin, dirs, dist, tri):
    """Distance from each hit point to the nearest edge of its triangle (inf for misses)."""
    out = np.full(len(dist), np.inf)
    hit = tri >= 0
    if not hit.any():
        return out
    o = np.asarray(origin, np.float64) - scene.centre
    p = o + dirs[hit] * dist[hit, None]
    tv = scene.vertices[scene.triangles[tri[hit]]]
    best = np.full(len(p), np.inf)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        ab = tv[:, b] - tv[:, a]
        s = np.clip(np.einsum("ij,ij->i", p - tv[:, a], ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (tv[:, a] + s[:, None] * ab), axis=1))
    out[hit] = best
    return out


def compare(geom, origin, dirs, max_range, factory_a, factory_b, tol=1e-4, edge=1e-3):
    """Cast the same rays with two backends after the engine's exact refinement.

    Returns a dict of counts; asserts: every ray hit by both agrees within ``tol`` m,
    and away from edges (hit points farther than ``edge`` from their triangle's edges
    in both answers) the hit/miss sets and the triangles are identical."""
    origin = np.asarray(origin, np.float64)
    sa = PreparedScene(geom, origin, max_range * 1.01 + 1.0, factory_a)
    sb = PreparedScene(geom, origin, max_range * 1.01 + 1.0, factory_b)
    da, ta, _ = sa.cast(origin, dirs, max_range)
    db, tb, _ = sb.cast(origin, dirs, max_range)
    near = (edge_distance(sa, origin, dirs, da, ta) < edge) | \
        (edge_distance(sb, origin, dirs, db, tb) < edge)
    both = (ta >= 0) & (tb >= 0)
    err = np.abs(da[both] - db[both])
    assert err.size == 0 or err.max() <= tol, f"range differs by {err.max():.3g} m"
    far = ~near
    hit_a, hit_b = ta[far] >= 0, tb[far] >= 0
    differ = np.nonzero(hit_a != hit_b)[0]
    assert differ.size == 0, f"{differ.size} rays away from edges hit in one backend only"
    same_tri = ta[far] == tb[far]
    assert same_tri.all(), f"{(~same_tri).sum()} rays away from edges hit other triangles"
    return {"rays": len(dirs), "hits_a": int((ta >= 0).sum()), "hits_b": int((tb >= 0).sum()),
            "near_edges": int(near.sum()), "max_err": float(err.max()) if err.size else 0.0}
