"""The elevation envelope (``casting.envelope``) that lets the watertight wrapper skip
rays that surely meet no hull box: never a ray that enters a box (conservative), and
from a sensor above a ground plane, the rays passing beyond the ground's edge are told
apart from those that may meet something (tight)."""

import numpy as np
import pytest

from rls_addon.core.casting.envelope import ElevationEnvelope

from .scenes import rays_entering_boxes


def enters(origin, directions, lo, hi):
    """(N,) bool: the ray enters (or starts in) some box: an exact slab test."""
    return rays_entering_boxes(origin, directions, lo, hi)


def some_directions(rng, n=20_000):
    d = rng.normal(size=(n, 3))
    d[rng.random(d.shape) < 0.1] = 0.0  # rays in the axis planes and along the axes
    d = d[np.linalg.norm(d, axis=1) > 0]
    return d / np.linalg.norm(d, axis=1)[:, None]


def boxes_around(rng, k=40):
    """Boxes everywhere around the origin: beside it, across the -x axis (where the
    azimuth wraps), over and under it, far and small, and one holding the origin."""
    lo = rng.uniform(-60, 60, (k, 3))
    hi = lo + rng.uniform(0.01, 8, (k, 3))
    special = np.array([[-30, -1, -2, -20, 1, 3],      # across the -x axis
                        [-3, -3, -10, 3, 3, -5],       # under the origin
                        [1, -2, 4, 2, 2, 9],           # above it, beside the z axis
                        [100, 100, 0, 100.5, 100.2, 0.1],
                        [-1e-9, -5, -1, 4, 5, 1]])     # touching the origin
    return np.concatenate([lo, special[:, :3]]), np.concatenate([hi, special[:, 3:]])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_ray_that_enters_a_box_is_skipped(seed):
    rng = np.random.default_rng(seed)
    lo, hi = boxes_around(rng)
    d = some_directions(rng)
    for origin in (np.zeros(3), rng.uniform(-40, 40, 3), np.array([-25.0, 0.0, 0.0])):
        env = ElevationEnvelope(origin, lo, hi)
        hit = enters(origin, d, lo, hi)
        assert hit.sum() > 100
        assert np.all(env.may_meet(d)[hit])


def test_a_box_holding_the_origin_lets_every_ray_through():
    d = some_directions(np.random.default_rng(4), 2000)
    env = ElevationEnvelope(np.zeros(3), np.array([[-1.0, -1, -1]]), np.array([[1.0, 1, 1]]))
    assert env.may_meet(d).all()


def test_rays_beyond_the_ground_edge_are_skipped():
    """A 100 m ground (a grid of thin boxes) and a 4.8 m box 20 m out, the sensor 5 m
    up: rays just below the horizon pass over the ground's edge, and only those towards
    the box may meet something."""
    s = np.linspace(-50, 50, 11)
    gx, gy = np.meshgrid(s[:-1], s[:-1], indexing="ij")
    lo = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, -0.01)], 1)
    hi = lo + [10, 10, 0.02]
    lo, hi = np.vstack([lo, [[20, -1, 0]]]), np.vstack([hi, [[22, 1, 4.8]]])
    env = ElevationEnvelope(np.array([0.0, 0.0, 5.0]), lo, hi)
    az = np.radians(np.arange(0, 360, 0.5))
    el = np.radians(-1.5)  # reaches the ground 190 m out, beyond its edge
    d = np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el),
                  np.full(az.size, np.sin(el))], 1)
    may = env.may_meet(d)
    towards_box = np.abs(np.degrees(np.arctan2(d[:, 1], d[:, 0]))) < 3.5  # 2.9 + a sector
    assert may[0] and not may[~towards_box].any()
    assert env.may_meet(np.array([[0.1, 0.0, -1.0]])).all()  # steeply down: the ground
