"""The footprint's compiled stages (native/c/edges.c) give what their numpy references
give: the same depth-edge pairs, and whole frames byte-identical either way."""

import hashlib
from types import SimpleNamespace

import numpy as np
import pytest

from rls_addon.core.physics import depth_edges, footprint
from rls_addon.core.physics.depth_edges import edges_numpy
from tests.core.built import require_built
from tests.core.test_footprint import device, edge_scene, grid, scan


@pytest.fixture(scope="module")
def native():
    return require_built(depth_edges.KERNEL)[0]


def random_pairs(n, seed, per_ray_origins):
    """Rays on a few planes (so many pairs lie near the step, on either side of it),
    some misses, some grazing or zero normals, and random neighbour pairs."""
    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    plane = rng.integers(0, 4, n)
    normals = rng.normal(size=(4, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals[plane]
    normals[rng.random(n) < 0.05] = 0.0
    grazing = rng.random(n) < 0.05
    normals[grazing] = np.cross(dirs[grazing], [0.0, 0.0, 1.0])
    dist = rng.uniform(0.5, 80.0, n)
    near = rng.random(n) < 0.3
    dist[near] += rng.choice([-0.1, 0.1, 0.05, 1e-9], size=np.count_nonzero(near))
    hit = rng.random(n) < 0.85
    dist[~hit] = np.inf
    origins = rng.normal(size=(n, 3)) * 5 if per_ray_origins else rng.normal(size=(1, 3))
    a = rng.integers(0, n, 4 * n)
    b = np.where(rng.random(4 * n) < 0.5, (a + 1) % n, rng.integers(0, n, 4 * n))
    return a, b, hit, dist, normals, dirs, origins


@pytest.mark.parametrize("per_ray_origins", [False, True])
@pytest.mark.parametrize("step", [0.1, 0.0, 5.0])
def test_compiled_edges_are_the_reference_edges(native, per_ray_origins, step):
    args = random_pairs(50_000, 7, per_ray_origins)
    want = edges_numpy(*args, step)
    got = depth_edges._edges_native(native, *args, step)
    assert 0 < np.count_nonzero(want) < len(want)
    np.testing.assert_array_equal(got, want)


def frame_digests(monkeypatch, modules, scene, mode, stat, **settings):
    """{compiled: sha256 of a footprint frame's points} with the compiled kernels of
    ``modules`` on and off (the Mid-40's figures, noise on); each frame must have some
    ``stat``."""
    pattern, _, _ = grid(rows=300)
    got = {}
    for compiled in (True, False):
        for module in modules:
            monkeypatch.setattr(module, "compiled", compiled)
        res = scan(scene, pattern, device(mode=mode, figures=((0.10, 90.0), (0.80, 260.0))),
                   noise=True, **settings)
        got[compiled] = hashlib.sha256(res.points.tobytes()).hexdigest()
        assert res.stats[stat] > 0
    return got


@pytest.mark.parametrize("mode", ["strongest", "dual"])
def test_frames_are_byte_identical_with_compiled_or_numpy_edges(native, monkeypatch, mode):
    got = frame_digests(monkeypatch, [depth_edges], edge_scene(), mode, "footprint_rays",
                        seed=4, weather="fog:visibility=80")
    assert got[True] == got[False]


@pytest.fixture(scope="module")
def native_probes():
    return require_built(footprint.PROBE_SECTORS, footprint.RING_RAYS)


@pytest.mark.parametrize("divergence", [(3e-3, 1.5e-3), (2e-3, 2e-3), (0.0, 1e-3)])
def test_compiled_probes_are_the_reference_probes(native_probes, monkeypatch, divergence):
    """Random directions (some vertical, some repeated, some neighbours straight above
    or beside: sectors on a boundary), random pairs."""
    rng = np.random.default_rng(11)
    n = 40_000
    dirs = rng.normal(size=(n, 3))
    dirs[rng.random(n) < 0.02] = (0.0, 0.0, 1.0)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    a = rng.integers(0, n, 3 * n)
    b = np.where(rng.random(3 * n) < 0.5, (a + 1) % n, rng.integers(0, n, 3 * n))
    same = rng.random(3 * n) < 0.01
    b[same] = a[same]
    # a grid: neighbours straight above and beside each other
    az, el = np.meshgrid(np.linspace(-1, 1, 50), np.linspace(-0.3, 0.3, 20))
    g = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)
    g = g.reshape(-1, 3)
    dirs = np.concatenate([dirs, g])
    idx = np.arange(n, n + len(g)).reshape(20, 50)
    a = np.concatenate([a, idx[:, :-1].ravel(), idx[:-1].ravel()])
    b = np.concatenate([b, idx[:, 1:].ravel(), idx[1:].ravel()])
    want = footprint.probe_rays_numpy(a, b, dirs, divergence)
    got = footprint.probe_rays(a, b, dirs, divergence)
    for w, x in zip(want, got):
        assert w.dtype == x.dtype
        np.testing.assert_array_equal(x, w)
    rows = np.unique(a[::7])
    np.testing.assert_array_equal(footprint.whole_rings(rows, dirs, divergence),
                                  footprint.ring_directions(dirs[rows], divergence)
                                  .reshape(-1, 3))


@pytest.mark.parametrize("mode", ["strongest", "dual"])
def test_frames_are_byte_identical_with_compiled_or_numpy_probes(native_probes, monkeypatch,
                                                                  mode):
    got = frame_digests(monkeypatch, [footprint], edge_scene(), mode, "footprint_rays", seed=4)
    assert got[True] == got[False]


@pytest.fixture(scope="module")
def native_edge_probes():
    return require_built(footprint.EDGE_SECTORS, footprint.RING_RAYS)


@pytest.mark.parametrize("per_ray_origins", [False, True])
@pytest.mark.parametrize("cap", [100_000, 1])
def test_probes_picked_while_testing_the_edges_are_the_reference_probes(
        native_edge_probes, monkeypatch, per_ray_origins, cap):
    """``edge_probes`` (the depth-edge test and the probe sectors in one pass) gives the
    probes of ``probe_rays_numpy`` over ``edges_numpy``'s pairs: random rays and pairs
    with directions repeated and vertical (thousands of sectors left to numpy), with
    room for them all, and with room for one per share (more: the frame is done in two
    steps)."""
    a, b, hit, dist, normals, dirs, origins = random_pairs(50_000, 3, per_ray_origins)
    dirs[::97] = (0.0, 0.0, 1.0)
    b[::89] = a[::89]
    pattern = SimpleNamespace(_neighbour_pairs=(a, b))
    monkeypatch.setattr(footprint, "_AMBIGUOUS_CAP", cap)
    two_steps = []
    monkeypatch.setattr(footprint, "probe_rays",
                        lambda *args: two_steps.append(1) or footprint.probe_rays_numpy(*args))
    edge = edges_numpy(a, b, hit, dist, normals, dirs, origins, 0.1)
    want = footprint.probe_rays_numpy(a[edge], b[edge], dirs, (2e-3, 1e-3))
    got = footprint.edge_probes(pattern, hit, dist, normals, dirs, origins, 0.1, (2e-3, 1e-3))
    assert len(want[0]) > 10_000
    assert bool(two_steps) == (cap == 1)
    for w, x in zip(want, got):
        assert w.dtype == x.dtype
        np.testing.assert_array_equal(x, w)


def test_frames_are_byte_identical_with_probes_picked_in_one_pass_or_two(
        native_edge_probes, monkeypatch):
    """Off: the edge pairs listed, then their probes (both compiled)."""
    scene, (pattern, _, _) = edge_scene(), grid(rows=300)
    got = {}
    for fused in (True, False):
        monkeypatch.setattr(footprint.EDGE_SECTORS, "get",
                            footprint.EDGE_SECTORS.get if fused else (lambda: None))
        res = scan(scene, pattern, device(mode="dual"), noise=True, seed=4)
        assert res.stats["footprint_rays"] > 0
        got[fused] = hashlib.sha256(res.points.tobytes()).hexdigest()
    assert got[True] == got[False]
