"""The ghost bounces' compiled set-up and landing (native/c/ghosts.c) are their numpy
references' (``ghost.aim_numpy``, ``ghost.land_numpy``) to the bit; frames with ghosts
are byte-identical with the kernels or without them (tests/core/test_assemble.py)."""

import numpy as np
import pytest

from rls_addon.core.physics import ghost
from tests.core.built import both_ways, require_built


@pytest.fixture(scope="module")
def native():
    return require_built(ghost.AIM, ghost.LAND)


def same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and \
        np.array_equal(a.view(np.uint8), b.view(np.uint8))


def same_aim(x, y):
    return x.glossy_hits == y.glossy_hits and all(
        same(getattr(x, k), getattr(y, k)) for k in ("chosen", "a", "r", "p", "start"))


def returns(n, seed, objects=30, materials=6, per_ray_origins=False):
    """Random returns: directions and normals of any sign (beams from both sides),
    ranges over four decades, a quarter of the rays invalid."""
    rng = np.random.default_rng(seed)
    dirs = rng.standard_normal((n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    normals = rng.standard_normal((n, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    surface = np.stack([rng.integers(0, objects, n), rng.integers(0, materials, n)],
                       1).astype(np.int32)
    origins = rng.uniform(-50, 50, (n if per_ray_origins else 1, 3))
    return dict(valid=rng.random(n) < 0.75, surface=surface, uniforms=rng.random(n),
                dist=10.0 ** rng.uniform(-1, 3, n), dirs=dirs, normals=normals,
                origins=origins)


def both(monkeypatch, fn, *args):
    return both_ways(monkeypatch, ghost, fn, *args)


@pytest.mark.parametrize("per_ray_origins", [False, True])
@pytest.mark.parametrize("glossy_objects", [False, True])
def test_compiled_aim_is_the_reference(native, monkeypatch, per_ray_origins, glossy_objects):
    r = returns(50_000, 1 + per_ray_origins, per_ray_origins=per_ray_origins)
    obj = np.zeros(30, bool)
    if glossy_objects:
        obj[[3, 7, 29]] = True
    tables = (obj, np.array([True, False, True, False, False, True]),
              np.array([0.5, 1.0, 0.25, 1.0, 0.0, 1.0]))
    args = (r["valid"], r["surface"], tables, r["uniforms"], r["dist"], r["dirs"],
            r["normals"], r["origins"])
    got, want = both(monkeypatch, ghost.aim, *args)
    assert 1000 < len(want.chosen) < want.glossy_hits < 50_000
    assert same_aim(got, want)
    # on objects that are not glossy: materials 1, 3 and 4 are not, 4 never bounces
    # and 5 always does
    surf = r["surface"][want.chosen]
    mat = surf[~obj[surf[:, 0]], 1]
    assert 5 in mat and not np.isin(mat, [1, 3, 4]).any()
    assert glossy_objects == np.isin(surf[:, 1], [1, 3]).any()


def test_aim_with_nothing_glossy_and_with_no_rays(native, monkeypatch):
    r = returns(1000, 3)
    none = (np.zeros(30, bool), np.zeros(6, bool), np.ones(6))
    got, want = both(monkeypatch, ghost.aim, r["valid"], r["surface"], none, r["uniforms"],
                     r["dist"], r["dirs"], r["normals"], r["origins"])
    assert same_aim(got, want) and want.glossy_hits == 0 and len(want.chosen) == 0
    empty = returns(0, 4)
    every = (np.zeros(30, bool), np.ones(6, bool), np.ones(6))
    got, want = both(monkeypatch, ghost.aim, empty["valid"], empty["surface"], every,
                     empty["uniforms"], empty["dist"], empty["dirs"], empty["normals"],
                     empty["origins"])
    assert same_aim(got, want) and len(want.r) == 0


def test_aim_refuses_a_surface_outside_its_tables(native):
    r = returns(100, 5)
    r["surface"][10, 1] = 6
    r["valid"][10] = True
    tables = (np.zeros(30, bool), np.ones(6, bool), np.ones(6))
    with pytest.raises(ValueError, match="outside the scene"):
        ghost.aim(r["valid"], r["surface"], tables, r["uniforms"], r["dist"], r["dirs"],
                  r["normals"], r["origins"])


def test_the_reflection_is_a_mirror_and_the_start_lies_on_the_beams_side(native):
    """Analytic: a beam along +x onto a wall facing -x (either normal sign) comes back
    along -x, and starts on the sensor's side of the wall."""
    for sign in (1.0, -1.0):
        dirs = np.array([[1.0, 0.0, 0.0]])
        normals = np.array([[-sign, 0.0, 0.0]])
        tables = (np.zeros(1, bool), np.ones(1, bool), np.ones(1))
        got = ghost.aim(np.ones(1, bool), np.zeros((1, 2), np.int32), tables, np.zeros(1),
                        np.array([5.0]), dirs, normals, np.zeros((1, 3)))
        assert np.array_equal(got.r, [[-1.0, 0.0, 0.0]])
        assert np.array_equal(got.p, [[5.0, 0.0, 0.0]])
        assert 5.0 - 1e-4 < got.start[0, 0] < 5.0


def landing(seed, n=40_000, m=8_000, rmax=120.0):
    rng = np.random.default_rng(seed)
    r = returns(n, seed)
    r["valid"][:] = True
    tables = (np.zeros(30, bool), np.ones(6, bool), np.full(6, m / n))
    bounce = ghost.aim_numpy(r["valid"], r["surface"], tables, r["uniforms"], r["dist"],
                             r["dirs"], r["normals"], r["origins"])
    k = len(bounce.chosen)
    b = rng.uniform(0.0, 150.0, k)
    tri = np.where(rng.random(k) < 0.8, rng.integers(0, 1000, k), -1)
    b[tri < 0] = np.inf
    n2 = rng.standard_normal((k, 3))
    return bounce, b, tri, n2, rmax, r


def test_compiled_landing_is_the_reference(native):
    bounce, b, tri, n2, rmax, r = landing(6)
    out = {}
    for compiled in (True, False):
        ghost.compiled = compiled
        try:
            valid, dist, normals = r["valid"].copy(), r["dist"].copy(), r["normals"].copy()
            got = ghost.land(bounce, b, tri, n2, rmax, valid, dist, normals, r["surface"],
                             np.linspace(0.1, 0.9, 6))
        finally:
            ghost.compiled = True
        out[compiled] = got + (valid, dist, normals)
    assert all(same(x, y) for x, y in zip(out[True], out[False]))
    fi, flag, last, mirror, valid, dist, normals = out[False]
    # some found nothing, some were too far in total, the rest became ghosts
    beyond = (tri >= 0) & ~np.isin(np.arange(len(tri)), fi)
    assert 0 < len(fi) < len(tri) and beyond.any() and (tri < 0).any()
    assert flag.sum() == len(fi) and not valid[bounce.chosen[tri < 0]].any()
    assert np.all(dist[bounce.chosen[fi]] <= rmax)
    # the second leg is measured from the mirror point, not from the lifted start
    a = bounce.a[fi]
    assert np.all(np.abs(dist[bounce.chosen[fi]] - (a + b[fi])) <= 1e-6 + 4.01e-6 * a)


def test_land_refuses_a_mirror_outside_the_material_table(native):
    bounce, b, tri, n2, rmax, r = landing(7, n=200, m=100)
    tri[:] = 0
    b[:] = 1.0
    surface = r["surface"].copy()
    surface[bounce.chosen[0], 1] = 99
    with pytest.raises(ValueError, match="material table"):
        ghost.land(bounce, b, tri, n2, 1e6, r["valid"].copy(), r["dist"].copy(),
                   r["normals"].copy(), surface, np.ones(6))
