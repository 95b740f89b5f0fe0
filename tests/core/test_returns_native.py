"""A static cast's returns in C (native/c/returns.c) are their numpy reference's
(``returns.static_returns_numpy``) to the bit; whole frames are byte-identical with the
kernel or without it (tests/core/test_assemble.py switches it with the others)."""

import numpy as np
import pytest

from rls_addon.core.world import returns
from tests.core.built import both_ways, require_built


@pytest.fixture(scope="module")
def native():
    return require_built(returns.STATIC_RETURNS)


def both(monkeypatch, *args):
    return both_ways(monkeypatch, returns, returns.static_returns, *args)


def test_compiled_returns_are_the_reference(native, monkeypatch):
    rng = np.random.default_rng(3)
    n, rows = 100_000, 5000
    tri = np.where(rng.random(n) < 0.6, rng.integers(0, rows, n), -1)
    dist = np.where(tri >= 0, rng.uniform(0.0, 250.0, n), np.inf)
    dist[:6] = [0.3, 200.0, np.nextafter(0.3, 0), np.nextafter(200.0, 300), np.nan, -0.0]
    tri[:6] = 7
    table = rng.integers(-5, 2**31 - 1, (rows, 2)).astype(np.int32)
    (valid, surface), (want_valid, want_surface) = both(monkeypatch, dist, tri, table,
                                                        0.3, 200.0)
    assert valid.dtype == want_valid.dtype == np.bool_ and np.array_equal(valid, want_valid)
    assert surface.dtype == np.int32 and np.array_equal(surface, want_surface)
    # the bounds are inclusive, NaN never returns, a miss gets the table's last row
    assert valid[:6].tolist() == [True, True, False, False, False, False]
    assert np.array_equal(surface[tri < 0], np.broadcast_to(table[-1], (np.sum(tri < 0), 2)))
    assert 0.3 < want_valid.mean() < 0.6


def test_returns_of_an_empty_table_and_of_no_rays(native, monkeypatch):
    none = np.zeros((0, 2), np.int32)
    (v, s), (wv, ws) = both(monkeypatch, np.full(3, np.inf), np.full(3, -1), none, 0.1, 9.0)
    assert not v.any() and np.array_equal(s, ws) and s.shape == (3, 2)
    (v, s), _ = both(monkeypatch, np.zeros(0), np.zeros(0, np.int64), np.ones((4, 2), np.int32),
                     0.1, 9.0)
    assert v.shape == (0,) and s.shape == (0, 2)


def test_a_triangle_outside_the_table_is_refused(native):
    with pytest.raises(IndexError, match="outside the scene"):
        returns.static_returns(np.ones(3), np.array([0, 4, 1]), np.ones((4, 2), np.int32),
                               0.0, 9.0)


@pytest.mark.parametrize("threads", [1, 3, 5])
def test_every_share_writes_its_own_rays_and_reports_a_bad_row(native, monkeypatch, threads):
    monkeypatch.setattr(returns.kernels, "threads", lambda: threads)
    rng = np.random.default_rng(5)
    n, rows = 80_000, 300
    tri = np.where(rng.random(n) < 0.7, rng.integers(0, rows, n), -1)
    dist = rng.uniform(0.0, 50.0, n)
    table = rng.integers(0, 1000, (rows, 2)).astype(np.int32)
    (v, s), (wv, ws) = both(monkeypatch, dist, tri, table, 1.0, 40.0)
    assert np.array_equal(v, wv) and np.array_equal(s, ws)
    tri[-1] = rows  # in the last share
    with pytest.raises(IndexError):
        returns.static_returns(dist, tri, table, 1.0, 40.0)


def _geometry(rng, triangles, objects, materials):
    from rls_addon.core.scene.geometry import MaterialInfo, ObjectInfo, SceneGeometry

    v = rng.normal(size=(3 * triangles, 3))
    return SceneGeometry(v, np.arange(3 * triangles).reshape(-1, 3),
                         rng.integers(0, len(objects), triangles),
                         rng.integers(0, len(materials), triangles),
                         [ObjectInfo(o) for o in objects], [MaterialInfo(m) for m in materials])


@pytest.mark.parametrize("static_triangles", [0, 1, 700])
def test_a_moving_worlds_returns_are_its_bodies_own(monkeypatch, static_triangles):
    """A world with moving bodies finds every ray's returns in one pass over all the
    bodies' rows (``World.returns``): what the range test and ``World.surface_ids``
    (body by body, the reference) give, misses included (the static scene's first
    row), frame after frame with the same bodies, with the kernel and without."""
    from types import SimpleNamespace

    from rls_addon.core.world.world import World

    rng = np.random.default_rng(11)
    objects, materials = ["road", "car", "bus", "bike"], ["asphalt", "paint", "glass"]
    static = SimpleNamespace(geometry=_geometry(rng, static_triangles, objects, materials))
    bodies = [SimpleNamespace(geometry=_geometry(rng, k, objects, materials))
              for k in (40, 1, 300)]
    for frame in range(2):
        world = World(static, bodies)
        n = 50_000
        body = rng.integers(-1, 4, n)
        body[(body == 0)] = -1 if static_triangles == 0 else 0
        counts = np.array([static_triangles, 40, 1, 300])
        tri = np.where(body >= 0, (rng.random(n) * counts[body]).astype(np.int64), -1)
        dist = np.where(body >= 0, rng.uniform(0.0, 120.0, n), np.inf)
        want = (returns.in_range(dist, tri, 0.5, 100.0), world.surface_ids(body, tri))
        for compiled in (True, False):
            monkeypatch.setattr(returns, "compiled", compiled)
            valid, surface = world.returns(dist, body, tri, 0.5, 100.0)
            assert np.array_equal(valid, want[0]) and valid.dtype == np.bool_
            assert np.array_equal(surface, want[1]) and surface.dtype == np.int32
        assert want[0].any() and (body == -1).any() and (body == 3).any()
