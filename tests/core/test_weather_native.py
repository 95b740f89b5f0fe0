"""The weather's compiled false returns (native/c/weather.c) are their numpy reference's
(``weather.false_returns_numpy``) to the bit, its inversion of the CDF is numpy's own
np.interp, and weather frames are byte-identical with it or without it."""

import numpy as np
import pytest

from rls_addon.core.physics import depth_edges, weather
from tests.core.built import both_ways, require_built
from tests.core.test_footprint import edge_scene
from tests.core.test_footprint_native import frame_digests


@pytest.fixture(scope="module")
def native():
    return require_built(weather.FALSE_RETURNS)[0]


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def both(monkeypatch, *args):
    return both_ways(monkeypatch, weather, weather.false_returns, *args)


@pytest.mark.parametrize("spec", ["fog:visibility=1", "fog:visibility=50", "rain:rate=10",
                                  "snow:rate=2"])
def test_compiled_false_returns_are_the_reference(native, monkeypatch, spec):
    alpha = weather.parse_weather(spec).alpha
    rng = np.random.default_rng(1)
    n = 100_000
    u_medium, u_range = rng.random(n), rng.random(n)
    u_range[:3] = [0.0, 0.5, np.nextafter(1.0, 0.0)]
    u_medium[:3] = 0.0
    hit = rng.random(n) < 0.7
    dist = np.where(hit, rng.uniform(0.5, 130.0, n), np.inf)
    got, want = both(monkeypatch, alpha, u_medium, u_range, hit, dist, 1.0, 120.0)
    assert 0 < len(want[0]) < n
    assert same_bits(got[0], want[0]) and same_bits(got[1], want[1])


@pytest.mark.parametrize("threads", [1, 3, 5])
def test_compiled_false_returns_join_their_shares_in_ray_order(native, monkeypatch, threads):
    """Each share of rays writes its false returns from its first ray's slot on; the
    shares are then moved down to follow each other (one share with none at all)."""
    monkeypatch.setattr(weather.kernels, "threads", lambda: threads)
    alpha = weather.parse_weather("fog:visibility=20").alpha
    rng = np.random.default_rng(4)
    n = 100_000
    u_medium, u_range = rng.random(n), rng.random(n)
    u_medium[25_000:50_000] = 1.0  # the second of four shares draws none
    hit = rng.random(n) < 0.5
    dist = np.where(hit, rng.uniform(0.5, 130.0, n), np.inf)
    got, want = both(monkeypatch, alpha, u_medium, u_range, hit, dist, 1.0, 120.0)
    assert len(want[0]) > 10_000 and not np.any((want[0] >= 25_000) & (want[0] < 50_000))
    assert same_bits(got[0], want[0]) and same_bits(got[1], want[1])


def test_the_inversion_is_numpys_interp(native, monkeypatch):
    """Every ray drawn and nothing in the way: the ranges are 1 / np.interp(u, cdf, x),
    for tables with ties, flat and steep stretches, infinities, and u on the table's
    points, between them and outside it."""
    rng = np.random.default_rng(2)
    cdf = np.sort(np.concatenate([rng.random(300), np.repeat(rng.random(20), 5),
                                  [0.0, 0.0, 1.0, 1.0]]))
    x = np.cumsum(rng.random(len(cdf)) * (rng.random(len(cdf)) < 0.7)) + 0.01
    x[10:14] = np.inf
    u = np.concatenate([rng.uniform(-0.2, 1.2, 50_000), cdf, np.nextafter(cdf, 2),
                        np.nextafter(cdf, -1), [np.inf, -np.inf]])
    monkeypatch.setattr(weather, "false_return_table", lambda *a: (cdf, x))
    monkeypatch.setattr(weather, "false_return_probability", lambda a: 2.0)
    n = len(u)
    args = (0.1, np.zeros(n), u, np.zeros(n, bool), np.zeros(n), 1.0, 120.0)
    (rows, ranges), (want_rows, want) = both(monkeypatch, *args)
    with np.errstate(divide="ignore"):
        assert same_bits(want, 1.0 / np.interp(u, cdf, x))
    assert same_bits(rows, want_rows) and same_bits(ranges, want)
    for table in (([0.2, 0.6], [1.0, 3.0]), ([0.5, 0.5], [1.0, 3.0])):
        monkeypatch.setattr(weather, "false_return_table", lambda *a, t=table: np.array(t))
        (_, got), (_, want) = both(monkeypatch, *args)
        assert same_bits(got, want)


@pytest.mark.parametrize("spec", ["fog:visibility=30", "rain:rate=20"])
def test_weather_frames_are_byte_identical_with_or_without_the_kernels(monkeypatch, spec):
    got = frame_digests(monkeypatch, [weather, depth_edges], edge_scene(gap=60.0), "dual",
                        "weather_returns", seed=9, weather=spec)
    assert got[True] == got[False]
