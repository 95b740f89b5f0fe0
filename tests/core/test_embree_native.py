"""The compiled Embree packet loop gives exactly what the Python packet loop gives."""

import numpy as np

from rls_addon.core.errors import CastingError
import pytest

from rls_addon.core.casting import embree as embree_caster

from .external_tools import require_backend


@pytest.fixture(autouse=True, scope="module")
def _embreex():
    require_backend(embree_caster, "embreex")


def scene(seed=0, n=4000):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-20, 20, (n, 3))
    v = (centres[:, None, :] + rng.normal(0, 1.0, (n, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * n).reshape(-1, 3)


def test_native_loop_is_built_for_the_tests():
    """make test builds it (tools/build_native.py); without it Embree is slower."""
    assert embree_caster._native_loop() is not None


@pytest.mark.parametrize("n_rays", [1, 15, 16, 17, 5000, 40000])
@pytest.mark.parametrize("per_ray_origins", [False, True])
def test_native_equals_python_packets(n_rays, per_ray_origins):
    v, t = scene()
    rng = np.random.default_rng(n_rays)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.uniform(-5, 5, (n_rays, 3)) if per_ray_origins else np.zeros((1, 3))
    native = embree_caster.EmbreeCaster(v, t, threads=2, native=True)
    python = embree_caster.EmbreeCaster(v, t, threads=2, native=False)
    assert "C loop" in native.describe() and "C loop" not in python.describe()
    dn, tn = native.cast(o, d, 30.0)
    dp, tp = python.cast(o, d, 30.0)
    assert np.array_equal(tn, tp)
    assert np.array_equal(dn, dp)
    if n_rays >= 5000:  # both hits and misses are exercised
        assert (tn >= 0).any() and (tn < 0).any()


@pytest.mark.parametrize("n_rays", [0, 1, 511, 512, 513, 40000])
def test_any_thread_count_casts_every_ray_once(n_rays):
    """Workers and the collecting caller take blocks of rays from one counter: any
    count of them (1: the caller alone) casts every ray exactly once."""
    from rls_addon.core.casting import triangle_planes

    v, t = scene(7)
    planes = triangle_planes(v, t)
    rng = np.random.default_rng(n_rays)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    want = None
    for threads in (1, 2, 3, 8):
        c = embree_caster.EmbreeCaster(v, t, threads=threads)
        got = c.cast_refined(np.zeros((1, 3)), d, 30.0, planes)
        assert all(len(x) == n_rays for x in got)
        if want is None:
            want = got
            python = embree_caster.EmbreeCaster(v, t, threads=1, native=False).cast(
                np.zeros((1, 3)), d, 30.0)
            assert np.array_equal(got[1], python[1])
        for x, y in zip(got, want):
            assert np.array_equal(x, y)


@pytest.mark.parametrize("per_ray_origins", [False, True])
def test_fused_refinement_equals_numpy_refinement(per_ray_origins):
    """The compiled loop refines each hit against its plane in float64 exactly as
    ``raycast.refine_hits`` does, and gives the same unit normals."""
    from rls_addon.core.casting import cast_exact, refine_hits, triangle_planes

    v, t = scene(3)
    planes = triangle_planes(v, t)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(30000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.uniform(-5, 5, (30000, 3)) if per_ray_origins else np.array([[0.3, -0.2, 0.1]])
    native = embree_caster.EmbreeCaster(v, t, threads=2, native=True)
    fused = native.cast_refined(o, d, 30.0, planes)
    assert fused is not None
    dist, tri, normals = fused
    raw_d, raw_t = native.cast(o, d, 30.0)
    ref_d, ref_n = refine_hits(v, t, o, d, raw_d, raw_t, planes)
    assert np.array_equal(tri, raw_t)
    assert np.allclose(dist, ref_d, rtol=0, atol=1e-12, equal_nan=False)
    assert np.array_equal(normals, ref_n)
    # The generic entry point takes the fused path, and without the C loop the numpy one.
    python = embree_caster.EmbreeCaster(v, t, threads=2, native=False)
    assert python.cast_refined(o, d, 30.0, planes) is None
    pd, pt, pn = cast_exact(python, o, d, 30.0, planes)
    assert np.array_equal(pt, tri) and np.allclose(pd, dist, rtol=0, atol=1e-12)
    assert np.array_equal(pn, normals)
    # The refined range is the exact distance to the hit triangle's plane.
    hit = tri >= 0
    x = np.broadcast_to(o, d.shape)[hit] + d[hit] * dist[hit, None]
    assert np.abs(np.einsum("ij,ij->i", planes[tri[hit], :3], x) - planes[tri[hit], 3]).max() < 1e-9


def test_started_cast_runs_while_python_works_and_may_be_dropped():
    v, t = scene(4)
    rng = np.random.default_rng(6)
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = embree_caster.EmbreeCaster(v, t, threads=2)
    from rls_addon.core.casting import triangle_planes

    planes = triangle_planes(v, t)
    pending = c.start_refined(np.zeros((1, 3)), d.copy(), 30.0, planes)
    busy = sum(np.sqrt(np.arange(1000.0)).sum() for _ in range(20))  # Python goes on meanwhile
    assert busy > 0
    dist, tri, normals = pending()
    assert pending()[0] is dist  # a second call gives the same arrays, without waiting
    want = c.cast_refined(np.zeros((1, 3)), d, 30.0, planes)
    assert np.array_equal(tri, want[1]) and np.array_equal(dist, want[0])
    # Dropped unfinished: its destructor waits for the workers before the arrays go.
    for _ in range(5):
        c.start_refined(np.zeros((1, 3)), d.copy(), 30.0, planes)
    import gc

    gc.collect()


def test_trace_order_changes_speed_not_results():
    """Rays traced in another order (shared packets) land in their own slots."""
    from rls_addon.core.casting import triangle_planes

    v, t = scene(7)
    planes = triangle_planes(v, t)
    rng = np.random.default_rng(8)
    d = rng.normal(size=(20011, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = embree_caster.EmbreeCaster(v, t, threads=2)
    order = rng.permutation(len(d))
    a = c.cast_refined(np.zeros((1, 3)), d, 30.0, planes)
    b = c.cast_refined(np.zeros((1, 3)), d, 30.0, planes, order=order)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    with pytest.raises(CastingError, match="order"):
        c.cast_refined(np.zeros((1, 3)), d, 30.0, planes, order=order[:-1])
