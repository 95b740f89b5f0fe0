"""The Embree backend against the exact numpy reference on analytic scenes."""

import numpy as np
import pytest

from rls_addon.core.casting import embree as embree_caster
from rls_addon.core.casting import NumpyCaster
from tests import parity

from .external_tools import require_backend


@pytest.fixture(autouse=True, scope="module")
def _embreex():
    require_backend(embree_caster, "embreex")


pytestmark = [
    # The numpy reference computes inf * 0 for rays parallel to a triangle's plane.
    pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning"),
]

MODES = ["packets", "embreex"]


def factory(mode):
    return embree_caster.EmbreeCaster.configured(mode=mode)


def rays():
    return np.concatenate([parity.random_directions(4000, seed=3), parity.lidar_directions(columns=180)])


@pytest.mark.parametrize("mode", MODES)
def test_plane(mode):
    g = parity.grid_plane()
    r = parity.compare(g, (0.3, -0.2, 0.0), rays(), 60.0, NumpyCaster, factory(mode))
    assert r["hits_b"] > 2000


@pytest.mark.parametrize("mode", MODES)
def test_plane_far_from_origin(mode):
    off = (1e5, -2e5, 30.0)
    g = parity.grid_plane(offset=off)
    origin = np.add(off, (0.3, -0.2, 0.0))
    r = parity.compare(g, origin, rays(), 60.0, NumpyCaster, factory(mode))
    assert r["hits_b"] > 2000


@pytest.mark.parametrize("mode", MODES)
def test_box_interior_every_ray_hits(mode):
    g = parity.box()
    d = rays()
    r = parity.compare(g, (0.5, 0.25, 0.1), d, 100.0, NumpyCaster, factory(mode))
    assert r["hits_a"] == r["hits_b"] == len(d)


@pytest.mark.slow  # a fine sphere against the numpy reference, inside and out
@pytest.mark.parametrize("mode", MODES)
def test_sphere_inside_and_outside(mode):
    g = parity.uv_sphere(radius=3.0, rings=24, segments=48)
    d = rays()
    r = parity.compare(g, (0.4, -0.7, 0.9), d, 50.0, NumpyCaster, factory(mode))
    assert r["hits_b"] == len(d)
    r = parity.compare(g, (9.0, 1.0, 0.5), d, 50.0, NumpyCaster, factory(mode))
    assert 0 < r["hits_b"] < len(d)


@pytest.mark.parametrize("mode", MODES)
def test_max_range_and_per_ray_origins(mode):
    g = parity.grid_plane(z=-2.0)
    d = parity.lidar_directions()
    c = embree_caster.EmbreeCaster(g.vertices, g.triangles, mode=mode)
    ref = NumpyCaster(g.vertices, g.triangles)
    o = np.zeros((1, 3))
    for max_dist in (3.0, 10.0):
        dist, tri = c.cast(o, d, max_dist)
        rd, rt = ref.cast(o, d, max_dist)
        ok = np.abs(rd[rt >= 0] - max_dist) > 1e-3  # not grazing the limit
        assert ((tri >= 0) == (rt >= 0))[rt >= 0][ok].all()
        assert (dist[tri >= 0] <= max_dist * (1 + 1e-6)).all()
    many = np.broadcast_to(o, d.shape)
    a = c.cast(many, d, 50.0)
    b = c.cast(o, d, 50.0)
    assert np.array_equal(a[1], b[1]) and np.array_equal(a[0], b[0])


def test_empty_and_zero_rays():
    c = embree_caster.EmbreeCaster(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    dist, tri = c.cast(np.zeros((1, 3)), parity.random_directions(10), 10.0)
    assert np.isinf(dist).all() and (tri == -1).all()
    g = parity.box()
    c = embree_caster.EmbreeCaster(g.vertices, g.triangles)
    dist, tri = c.cast(np.zeros((1, 3)), np.zeros((0, 3)), 10.0)
    assert dist.shape == (0,) and tri.dtype == np.int64


def test_packet_mode_is_used_and_threads_give_the_same_answer():
    g = parity.uv_sphere()
    c = embree_caster.EmbreeCaster(g.vertices, g.triangles)
    assert c.mode == "packets", embree_caster.packet_mode_error()
    d = parity.random_directions(100_000, seed=9)  # several chunks: the thread pool runs
    one = embree_caster.EmbreeCaster(g.vertices, g.triangles, threads=1).cast(
        np.zeros((1, 3)), d, 50.0)
    many = c.cast(np.zeros((1, 3)), d, 50.0)
    assert np.array_equal(one[1], many[1]) and np.array_equal(one[0], many[0])
