"""The weather's compiled kernel (native/interp.c) gives numpy's own np.interp values,
to the bit, and weather frames are byte-identical with it or without it."""

import hashlib

import numpy as np
import pytest

from rls_addon.core import kernels, weather
from tests.core.test_footprint import device, edge_scene, grid, scan


@pytest.fixture(scope="module")
def native():
    fn = kernels.INTERP.get()
    if fn is None:
        pytest.fail(f"the compiled interp is not built ({kernels.INTERP.error}): run "
                    "'make native' (make test does)")
    return fn


def same_bits(a, b):
    return np.array_equal(np.asarray(a).view(np.int64), np.asarray(b).view(np.int64))


@pytest.mark.parametrize("spec", ["fog:visibility=1", "fog:visibility=50", "rain:rate=10",
                                  "snow:rate=2"])
def test_compiled_interp_inverts_the_false_return_cdf_as_numpy_does(native, spec, monkeypatch):
    alpha = weather.parse_weather(spec).alpha
    u = np.random.default_rng(1).random(100_000)
    u[:4] = [0.0, 0.5, np.nextafter(1.0, 0.0), 0.25]
    got = weather.false_return_ranges(u, alpha, 1.0, 120.0)
    monkeypatch.setattr(kernels, "compiled", False)
    assert same_bits(got, weather.false_return_ranges(u, alpha, 1.0, 120.0))


def test_compiled_interp_edge_cases(native, monkeypatch):
    rng = np.random.default_rng(2)
    # ties, flat and steep stretches, points on the grid, outside it, NaN and infinities
    xp = np.sort(np.concatenate([rng.random(300), np.repeat(rng.random(20), 5),
                                 [0.0, 0.0, 1.0, 1.0]]))
    fp = np.cumsum(rng.random(len(xp)) * (rng.random(len(xp)) < 0.7))
    fp[10:14] = np.inf
    x = np.concatenate([rng.uniform(-0.2, 1.2, 50_000), xp, np.nextafter(xp, 2),
                        np.nextafter(xp, -1), [np.nan, np.inf, -np.inf]])
    got = kernels.interp(x, xp, fp)
    want = np.interp(x, xp, fp)
    assert same_bits(got, want)
    # a single step, and an xp of one value: numpy's own
    assert same_bits(kernels.interp(x, [0.2, 0.6], [1.0, 3.0]), np.interp(x, [0.2, 0.6], [1.0, 3.0]))
    assert same_bits(kernels.interp(x, [0.5, 0.5], [1.0, 3.0]), np.interp(x, [0.5, 0.5], [1.0, 3.0]))
    monkeypatch.setattr(kernels, "compiled", False)
    assert same_bits(kernels.interp(x, xp, fp), want)


@pytest.mark.parametrize("spec", ["fog:visibility=30", "rain:rate=20"])
def test_weather_frames_are_byte_identical_with_or_without_the_kernels(monkeypatch, spec):
    from rls_addon.core import depth_edges

    pattern, _, _ = grid(rows=300)
    figures = ((0.10, 90.0), (0.80, 260.0))
    got = {}
    for compiled in (True, False):
        monkeypatch.setattr(kernels, "compiled", compiled)
        monkeypatch.setattr(depth_edges, "compiled", compiled)
        res = scan(edge_scene(gap=60.0), pattern, device(mode="dual", figures=figures),
                   noise=True, seed=9, weather=spec)
        got[compiled] = hashlib.sha256(res.points.tobytes()).hexdigest()
        assert res.stats["weather_returns"] > 0
    assert got[True] == got[False]
