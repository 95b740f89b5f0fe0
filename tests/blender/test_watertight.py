"""Rays aimed exactly at shared edges and vertices of closed meshes never escape.

BVHTree works in float32 and lets such rays slip between neighbouring triangles
(about 1 in 10^4 here), and so does Embree without its robust mode; the engine's
watertight wrapper must catch every one, with the range refined in float64 (fused
into the compiled Embree loop)."""


import bmesh
import numpy as np
import pytest

from rls_addon.core.casting import BVHCaster
from rls_addon.core.casting import embree as embree_caster
from rls_addon.core.casting import WatertightCaster, cast_exact, triangle_planes
from tests.core.external_tools import require_backend

FACTORIES = {
    "bvhtree": BVHCaster,
    "embree": embree_caster.EmbreeCaster,
    "embree_fast": embree_caster.EmbreeCaster.configured(robust=False),
}


def closed_mesh(kind):
    bm = bmesh.new()
    if kind == "icosphere":
        bmesh.ops.create_icosphere(bm, subdivisions=4, radius=5.0)
    else:  # an axis-aligned cube with a grid on every face: the hardest case
        bmesh.ops.create_cube(bm, size=10.0)
        bmesh.ops.subdivide_edges(bm, edges=bm.edges, cuts=7, use_grid_fill=True)
        bmesh.ops.triangulate(bm, faces=bm.faces)
    v = np.array([tuple(x.co) for x in bm.verts], dtype=np.float64)
    f = np.array([[x.index for x in face.verts] for face in bm.faces], dtype=np.int64)
    bm.free()
    return v, f


def edge_and_vertex_targets(v, f, per_edge=40):
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    s = np.linspace(0.02, 0.98, per_edge)[:, None, None]
    on_edges = (v[e[:, 0]][None] * (1 - s) + v[e[:, 1]][None] * s).reshape(-1, 3)
    return np.concatenate([v, on_edges])


@pytest.mark.parametrize("backend", sorted(FACTORIES))
@pytest.mark.parametrize("kind", ["icosphere", "grid_cube"])
def test_no_ray_escapes_a_closed_mesh(kind, backend):
    if backend != "bvhtree":
        require_backend(embree_caster, "embreex")
    factory = FACTORIES[backend]
    v, f = closed_mesh(kind)
    planes = triangle_planes(v, f)
    targets = edge_and_vertex_targets(v, f)
    rng = np.random.default_rng(7)
    origins = np.concatenate([np.zeros((1, 3)), rng.uniform(-3, 3, (40, 3))])
    caster = WatertightCaster(factory, v, f)
    raw = factory(v, f)
    total = raw_misses = misses = 0
    worst = 0.0
    while total < 1_000_000:
        for o in origins:
            d = targets - o
            expected = np.linalg.norm(d, axis=1)
            d /= expected[:, None]
            raw_misses += int((raw.cast(o[None], d, 100.0)[1] < 0).sum())
            dist, tri, _ = cast_exact(caster, o[None], d, 100.0, planes)
            misses += int((tri < 0).sum())
            worst = max(worst, float(np.abs(dist - expected).max()))
            total += len(d)
            if total >= 1_000_000:
                break
    assert total >= 1_000_000
    assert misses == 0, f"{misses} of {total} rays escaped ({backend} alone: {raw_misses})"
    assert worst <= 1e-4  # the refined range is the distance to the aimed-at point
    print(f"{backend} {kind}: {raw_misses} of {total} escaped the backend alone")


@pytest.mark.parametrize("backend", ["embree", "embree_fast"])
@pytest.mark.parametrize("kind", ["icosphere", "grid_cube"])
def test_compiled_recheck_matches_the_numpy_reference(kind, backend):
    """The re-check in the compiled loop's threads wins back the same rays, with the
    same bits, as WatertightCaster._recheck in numpy (both from inside and outside)."""
    if not embree_caster.available() or embree_caster._native_loop() is None:
        pytest.fail("embreex and the compiled loop are needed (make test builds them)")
    v, f = closed_mesh(kind)
    planes = triangle_planes(v, f)
    targets = edge_and_vertex_targets(v, f)
    caster = WatertightCaster(FACTORIES[backend], v, f)
    rng = np.random.default_rng(11)
    for o in np.concatenate([np.zeros((1, 3)), rng.uniform(-3, 3, (4, 3)),
                             rng.uniform(8, 12, (3, 3))]):  # the last ones outside
        d = targets - o
        d /= np.linalg.norm(d, axis=1)[:, None]
        got = []
        for compiled in (True, False):
            caster.compiled, caster.retried = compiled, 0
            got.append((cast_exact(caster, o[None], d, 100.0, planes), caster.retried))
        caster.compiled = True
        (a, ra), (b, rb) = got
        assert ra == rb
        for x, y in zip(a, b):
            assert x.tobytes() == y.tobytes()


def test_bvhtree_refined_cast_matches_cast_then_refine():
    """BVHCaster.start_refined reads only the triangle of each ray and takes the range
    from its plane: the same bits as casting and refining (refine_hits), grazing rays
    (which keep BVHTree's own range) included."""
    from rls_addon.core.casting import refine_hits
    from rls_addon.core.casting.base import plane_ranges

    v, f = closed_mesh("grid_cube")
    planes = triangle_planes(v, f)
    caster = BVHCaster(v, f)
    rng = np.random.default_rng(5)
    # From just above the top face (z = 5), rays aimed at points of the cube, and rays
    # descending onto the top face at slopes under GRAZING
    o = np.array([[-5.5, 0.3, 5.0 + 4e-7]])
    d = np.concatenate([rng.uniform(-5, 5, (3000, 3)) - o,
                        [[1.0, 0.01 * k, -2e-7 * k] for k in range(1, 40)]])
    d /= np.linalg.norm(d, axis=1)[:, None]
    dist, tri = caster.cast(o, d, 100.0)
    want = (*refine_hits(None, None, o, d, dist, tri, planes), tri)
    got_dist, got_tri, got_normals = caster.start_refined(o, d, 100.0, planes)()
    hit = np.nonzero(tri >= 0)[0]
    usable = plane_ranges(planes[tri[hit]], o, d, hit)[1]
    assert len(hit) > 2000 and not usable.all()  # grazing hits among them
    for x, y in zip((got_dist, got_normals, got_tri), want):
        assert x.tobytes() == y.tobytes()


@pytest.mark.parametrize("origin", [(0.0, 0.0, 5.0), (30.0, -20.0, 1.0)])
def test_bvhtree_skips_only_rays_that_surely_miss(origin):
    """Behind the watertight wrapper BVHTree casts only the rays that may reach a hull
    box (from one origin, by the boxes' elevation envelope; per-ray origins, by the
    octant test): the same hits, bits and re-checks as casting every ray."""
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.device.presets import get_preset
    from tests.core.test_assemble import open_sky

    preset = get_preset("hesai_pandar64")
    d = preset.pattern().directions
    scene = PreparedScene(open_sky(), np.asarray(origin), preset.range.max_m, BVHCaster)
    caster, o = scene.caster, np.asarray(origin)[None] - scene.centre
    per_ray = np.repeat(o, len(d), axis=0) + np.linspace(0, 1, len(d))[:, None]
    for origins in (o, per_ray):
        assert len(caster.rows_worth_casting(origins, d, 120.0)) < 0.9 * len(d)
        got = []
        for skip in (True, False):
            caster.primary.skip_sure_misses, caster.retried = skip, 0
            got.append((cast_exact(caster, origins, d, 120.0, scene.planes), caster.retried))
        del caster.primary.skip_sure_misses
        (a, ra), (b, rb) = got
        assert ra == rb
        for x, y in zip(a, b):
            assert x.tobytes() == y.tobytes()
