"""The backends of platforms without embreex 4 (pyemblite: the macOS zips; Open3D:
where a user has it) against the exact numpy reference, and how backends are chosen
and reported per platform (``caster_factory``, ``backend_status``)."""

import numpy as np
import pytest

from rls_addon.core import casting
from rls_addon.core.casting import NumpyCaster, emblite, embree, embree_api, embree_loop, open3d_caster
from rls_addon.core.errors import CastingError
from tests import parity

from .external_tools import require_backend

# Each backend's library is required where a requirements file installs it: a missing one
# skips, or fails under RLS_REQUIRE_TOOLS=1 (make test).
LIBRARIES = {casting.EmbliteCaster: (emblite, "pyemblite"),
             casting.Open3DCaster: (open3d_caster, "open3d")}
BACKENDS = [pytest.param(casting.EmbliteCaster, id="pyemblite"),
            pytest.param(casting.Open3DCaster, id="open3d")]


@pytest.fixture(autouse=True)
def _library(request):
    """The library of the backend a test is parametrized with."""
    callspec = getattr(request.node, "callspec", None)
    backend = callspec.params.get("backend") if callspec else None
    if backend in LIBRARIES:
        require_backend(*LIBRARIES[backend])


# The numpy reference computes inf * 0 for rays parallel to a triangle's plane.
pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")


def rays():
    return np.concatenate([parity.random_directions(4000, seed=3),
                           parity.lidar_directions(columns=180)])


@pytest.fixture(autouse=True)
def fresh_status():
    casting.backend_status.cache_clear()
    yield
    casting.backend_status.cache_clear()


@pytest.mark.parametrize("backend", BACKENDS)
def test_plane_and_far_from_origin(backend):
    g = parity.grid_plane()
    r = parity.compare(g, (0.3, -0.2, 0.0), rays(), 60.0, NumpyCaster, backend)
    assert r["hits_b"] > 2000
    off = (1e5, -2e5, 30.0)
    g = parity.grid_plane(offset=off)
    r = parity.compare(g, np.add(off, (0.3, -0.2, 0.0)), rays(), 60.0, NumpyCaster,
                       backend)
    assert r["hits_b"] > 2000


@pytest.mark.parametrize("backend", BACKENDS)
def test_box_interior_every_ray_hits(backend):
    d = rays()
    r = parity.compare(parity.box(), (0.5, 0.25, 0.1), d, 100.0, NumpyCaster,
                       backend)
    assert r["hits_a"] == r["hits_b"] == len(d)


@pytest.mark.slow  # a fine sphere against the numpy reference, inside and out
@pytest.mark.parametrize("backend", BACKENDS)
def test_sphere_inside_and_outside(backend):
    g = parity.uv_sphere(radius=3.0, rings=24, segments=48)
    d = rays()
    r = parity.compare(g, (0.4, -0.7, 0.9), d, 50.0, NumpyCaster, backend)
    assert r["hits_b"] == len(d)
    r = parity.compare(g, (9.0, 1.0, 0.5), d, 50.0, NumpyCaster, backend)
    assert 0 < r["hits_b"] < len(d)


@pytest.mark.parametrize("backend", BACKENDS)
def test_max_range_per_ray_origins_and_threads(backend):
    g = parity.grid_plane(z=-2.0)
    d = parity.lidar_directions()
    c = backend(g.vertices, g.triangles)
    ref = NumpyCaster(g.vertices, g.triangles)
    o = np.zeros((1, 3))
    for max_dist in (3.0, 10.0):
        dist, tri = c.cast(o, d, max_dist)
        rd, rt = ref.cast(o, d, max_dist)
        ok = np.abs(rd[rt >= 0] - max_dist) > 1e-3  # not grazing the limit
        assert ((tri >= 0) == (rt >= 0))[rt >= 0][ok].all()
        assert ((tri >= 0) == (rt >= 0))[rt < 0].all()  # beyond the limit: misses
        assert (dist[tri >= 0] <= max_dist * (1 + 1e-6)).all()
        assert np.isinf(dist[tri < 0]).all()
    assert dist.dtype == np.float64 and tri.dtype == np.int64
    a = c.cast(np.broadcast_to(o, d.shape), d, 50.0)
    b = c.cast(o, d, 50.0)
    one = backend(g.vertices, g.triangles).cast(o, d, 50.0)  # a second build: the same
    assert np.array_equal(a[1], b[1]) and np.array_equal(a[0], b[0])
    assert np.array_equal(one[1], b[1]) and np.array_equal(one[0], b[0])
    with pytest.raises(CastingError, match="origins"):
        c.cast(np.zeros((2, 3)), d, 10.0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_empty_scene_and_zero_rays(backend):
    c = backend(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    dist, tri = c.cast(np.zeros((1, 3)), parity.random_directions(10), 10.0)
    assert np.isinf(dist).all() and (tri == -1).all()
    g = parity.box()
    dist, tri = backend(g.vertices, g.triangles).cast(np.zeros((1, 3)),
                                                                   np.zeros((0, 3)), 10.0)
    assert dist.shape == (0,) and tri.dtype == np.int64


@pytest.mark.parametrize("backend", BACKENDS)
def test_matches_embreex_on_a_lidar_frame(backend):
    """The same hits as the Embree backend on many triangles, after the engine's
    exact refinement (where macOS arm64 casts with Open3D, Linux casts with Embree)."""
    require_backend(embree, "embreex")
    rng = np.random.default_rng(4)
    g = parity.geometry(*_boxes(rng, 400))
    d = parity.lidar_directions(channels=64, columns=900)
    r = parity.compare(g, (0.0, 0.0, 1.5), d, 120.0, embree.EmbreeCaster, backend)
    assert r["hits_a"] > len(d) // 4


def _boxes(rng, k):
    lo = rng.uniform(-60, 60, (k, 3)) * (1, 1, 0.1)
    lo[:, 2] -= 1.0
    hi = lo + rng.uniform(0.5, 6, (k, 3))
    from rls_addon.core.casting.watertight import box_triangles

    return box_triangles(lo, hi)


def test_factory_prefers_embreex_pyemblite_open3d_then_bvhtree(monkeypatch):
    have = {"embree": True, "emblite": True, "open3d": True}
    monkeypatch.setattr(embree, "available", lambda: have["embree"])
    monkeypatch.setattr(emblite, "available", lambda: have["emblite"])
    monkeypatch.setattr(embree, "unavailable_reason",
                        lambda: "ModuleNotFoundError: No module named 'embreex'")
    monkeypatch.setattr(open3d_caster, "available", lambda: have["open3d"])
    monkeypatch.setattr(open3d_caster, "unavailable_reason",
                        lambda: "ModuleNotFoundError: No module named 'open3d'")
    assert casting.caster_factory("auto") == (embree.EmbreeCaster, None)
    assert casting.caster_factory("open3d") == (casting.Open3DCaster, None)
    assert casting.backend_names() == ("bvhtree", "embree", "open3d")
    have["embree"] = False  # the macOS zips: Embree 4 from pyemblite
    assert casting.caster_factory("auto") == (casting.EmbliteCaster, None)
    assert casting.caster_factory("embree") == (casting.EmbliteCaster, None)
    assert casting.backend_status("auto") == (
        "embree", "Embree 4 from the pyemblite wheel, one ray at a time on one core "
                  "(no embreex wheel for this platform)")
    assert casting.backend_names() == ("bvhtree", "embree", "open3d")
    casting.backend_status.cache_clear()
    have["emblite"] = False  # Open3D where a user has it, never silently
    assert casting.caster_factory("auto") == (casting.Open3DCaster, None)
    factory, notice = casting.caster_factory("embree")
    assert factory is casting.Open3DCaster and "Open3D" in notice and "embreex" in notice
    assert casting.caster_factory("bvhtree") == (casting.BVHCaster, None)
    assert casting.backend_status("auto") == (
        "open3d", "Open3D: Embree inside Open3D's RaycastingScene, all cores "
                  "(no Embree wheel for this platform)")
    have["open3d"] = False  # no backend wheel at all: BVHTree, and why
    assert casting.caster_factory("auto") == (casting.BVHCaster, None)
    factory, notice = casting.caster_factory("open3d")
    assert factory is casting.BVHCaster and "Open3D is not available" in notice
    casting.backend_status.cache_clear()
    backend, why = casting.backend_status("auto")
    assert backend == "bvhtree"
    assert why.startswith("BVHTree: no Embree build for this platform") and "embreex" in why
    assert casting.backend_status("bvhtree") == ("bvhtree", "BVHTree: as chosen (one core)")
    assert casting.backend_names() == ("bvhtree",)


def test_status_says_how_embree_runs(monkeypatch):
    require_backend(embree, "embreex")
    backend, why = casting.backend_status("auto")
    assert backend == "embree"
    if embree._native_loop() is not None:
        assert why.startswith("Embree with the compiled loop on ")
    casting.backend_status.cache_clear()
    monkeypatch.setattr(embree_loop, "_native_loop", lambda: None)
    monkeypatch.setattr(embree_loop, "native_loop_error",
                        lambda: "no compiled loop for this platform (_rls_native.dll is missing)")
    backend, why = casting.backend_status("embree")
    assert backend == "embree" and "packets from Python" in why and ".dll is missing" in why
    casting.backend_status.cache_clear()
    monkeypatch.setattr(embree_api, "_packet_library", lambda: None)
    monkeypatch.setattr(embree, "packet_mode_error", lambda: "OSError: libembree4 not found")
    backend, why = casting.backend_status("embree")
    assert backend == "embree" and "one core" in why and "libembree4 not found" in why


def test_status_is_worked_out_once_per_choice(monkeypatch):
    calls = []
    real = casting.caster_factory

    def counting(name="auto"):
        calls.append(name)
        return real(name)

    monkeypatch.setattr(casting, "caster_factory", counting)
    first = casting.backend_status("bvhtree")
    for _ in range(50):  # a panel redrawn
        assert casting.backend_status("bvhtree") == first
    assert calls == ["bvhtree"]
