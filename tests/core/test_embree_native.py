"""The compiled Embree packet loop gives exactly what the Python packet loop gives."""

import numpy as np
import pytest

embree_caster = pytest.importorskip("rls_addon.core.embree_caster")
if not embree_caster.available():
    pytest.skip(f"embreex missing: {embree_caster.unavailable_reason()}", allow_module_level=True)


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
