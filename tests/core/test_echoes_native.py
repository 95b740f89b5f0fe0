"""A footprint's echoes grouped and chosen in C (native/c/echoes.c) are the numpy
reference's (echoes.resolve_numpy) to the last bit: the reported echoes, their
intensities and ranks, the second echoes of dual return, the returns written back,
and whole frames."""

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from rls_addon.core.physics import echoes
from rls_addon.core.physics.detection import DetectionModel
from rls_addon.core.physics.footprint import RING, Beam
from tests.core.built import require_built
from tests.core.test_footprint import edge_scene
from tests.core.test_footprint_native import frame_digests


@pytest.fixture(scope="module")
def native():
    return require_built(echoes.GROUP, echoes.CHOOSE)


def random_beams(seed, mode, n=3000, n_c=900):
    """A frame of ``n`` rays of which ``n_c`` are footprint candidates: samples on a few
    objects at ranges that often lie near the separation of each other (so echoes
    split and merge), equal energies from different objects (ties), misses, ranges
    beyond the limits, NaN normals, invalid centres."""
    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    base = rng.uniform(0.3, 130.0, n)
    dist = base.copy()
    dist[rng.random(n) < 0.05] = np.inf
    valid = np.isfinite(dist) & (rng.random(n) < 0.95)
    surface = np.stack([rng.integers(0, 4, n), rng.integers(0, 5, n)], 1).astype(np.int32)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[rng.random(n) < 0.01] = np.nan
    ret = SimpleNamespace(dist=dist, valid=valid, surface=surface, normals=normals)
    rows = np.sort(rng.choice(n, n_c, replace=False))
    k = n_c * RING
    centre = np.repeat(base[rows], RING)
    step = rng.choice([0.0, 0.3, 0.999, 1.0, 1.001, 2.5, 12.0, -0.7, -1.5], size=k)
    sdist = centre + step
    sdist[rng.random(k) < 0.08] = np.inf
    stri = np.where(np.isfinite(sdist), rng.integers(0, 100, k), -1)
    ssurface = np.where(rng.random((k, 1)) < 0.6, np.repeat(surface[rows], RING, 0),
                        np.stack([rng.integers(0, 4, k), rng.integers(0, 5, k)], 1))
    snormals = np.where(rng.random((k, 1)) < 0.5, np.repeat(normals[rows], RING, 0),
                        rng.normal(size=(k, 3)))
    sdirs = np.repeat(dirs[rows], RING, 0) + rng.normal(size=(k, 3)) * 1e-3
    # some beams whose ring sub-rays send equal energies from other objects (ties)
    tie = np.nonzero(np.repeat(rng.random(n_c) < 0.15, RING))[0]
    first = tie - tie % RING
    for x in (sdist, stri, snormals, sdirs):
        x[tie] = x[first]
    ssurface[tie, 1] = ssurface[first, 1]
    ssurface[tie, 0] = tie % 3
    agree = rng.random(n_c) < 0.2          # some beams all on the centre's surface
    a = np.repeat(agree, RING)
    sdist[a] = centre[a]
    stri[a] = 1
    ssurface[a] = np.repeat(surface[rows], RING, 0)[a]
    sub = SimpleNamespace(beam=Beam((1e-3, 1e-3), mode, 1.0), rows=rows, dist=sdist,
                          tri=stri, surface=ssurface.astype(np.int32), normals=snormals,
                          dirs=sdirs, cast=k, probes=0)
    refl = rng.uniform(0.05, 0.9, 5)
    detect = rng.random(n)
    skip = rng.choice(n, 40, replace=False)
    return sub, ret, dirs, skip, refl, detect


def both(sub, ret, dirs, skip, refl, model, detect, alpha, atten, rmin=0.5, rmax=120.0):
    outs = []
    for fn in (echoes.resolve, echoes.resolve_numpy):
        r = copy.deepcopy(ret)
        got, stats = fn(sub, r, dirs, skip, refl, model, detect, 12345, alpha, atten,
                        rmin, rmax)
        outs.append((got, stats, r))
    return outs


@pytest.mark.filterwarnings("ignore:invalid value encountered")  # the NaN normals
@pytest.mark.parametrize("mode", ["strongest", "last", "dual"])
@pytest.mark.parametrize("model", [None, DetectionModel(((0.1, 40.0), (0.8, 110.0)))])
@pytest.mark.parametrize("air", [(0.0, 0.0), (0.02, 0.0), (0.0, 0.004), (0.06, 0.004)])
def test_compiled_echoes_are_the_reference_echoes(native, mode, model, air):
    sub, ret, dirs, skip, refl, detect = random_beams(7, mode)
    (got, gstats, gret), (want, wstats, wret) = both(
        sub, ret, dirs, skip, refl, model, detect if model else None, *air)
    assert gstats == wstats
    assert wstats["footprint_changed_rays"] > 400 and wstats["mixed_points"] > 0
    if mode == "dual":
        assert wstats["second_returns"] > 20
    for name in ("dist", "valid", "surface", "normals"):
        w, g = getattr(wret, name), getattr(gret, name)
        assert w.dtype == g.dtype, name
        assert w.tobytes() == g.tobytes(), name
    for name in ("rows", "rho_cos", "carla", "extra_parent", "extra_dist", "extra_surface",
                 "extra_normals", "extra_rho_cos", "extra_carla", "return_index",
                 "num_returns"):
        w, g = getattr(want, name), getattr(got, name)
        assert w.shape == g.shape, name
        assert w.tobytes() == np.asarray(g, w.dtype).tobytes(), name
        assert w.dtype == g.dtype, name


def test_when_every_beam_agrees_nothing_changes(native):
    sub, ret, dirs, skip, refl, detect = random_beams(3, "dual", n_c=50)
    sub.dist = np.repeat(ret.dist[sub.rows], RING)
    sub.tri = np.ones(len(sub.dist), np.int64)
    sub.surface = np.repeat(ret.surface[sub.rows], RING, 0)
    ret.valid[sub.rows] = np.isfinite(ret.dist[sub.rows]) & (ret.dist[sub.rows] >= 0.5) \
        & (ret.dist[sub.rows] <= 120.0)
    missing = ~ret.valid[sub.rows]  # a centre that returns nothing disagrees: drop them
    sub.rows = sub.rows[~missing]
    keep = np.repeat(~missing, RING)
    sub.dist, sub.tri = sub.dist[keep], sub.tri[keep]
    sub.surface, sub.normals, sub.dirs = sub.surface[keep], sub.normals[keep], sub.dirs[keep]
    (got, gstats, gret), (want, wstats, _) = both(sub, ret, dirs, None, refl, None, None,
                                                  0.0, 0.0)
    assert got is None and want is None and gstats == wstats
    assert gret.dist.tobytes() == ret.dist.tobytes()


@pytest.mark.parametrize("mode", ["strongest", "last", "dual"])
def test_frames_are_byte_identical_with_compiled_or_numpy_echoes(native, monkeypatch, mode):
    got = frame_digests(monkeypatch, [echoes], edge_scene(), mode, "footprint_changed_rays",
                        seed=4, weather="rain:rate=20")
    assert got[True] == got[False]
