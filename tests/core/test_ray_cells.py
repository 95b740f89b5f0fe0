"""``RayCells.segments`` (every box's cone of rays, all boxes' cell spans turned into
runs of the sorted rays in one pass) against a brute force over every ray: each box's
runs hold every ray whose line passes within its sphere ahead of the origins, each ray
once, and far fewer rays than all for a small far box; the same for ``within_many``
against ``within`` one direction at a time."""

import math

import numpy as np
import pytest

from rls_addon.core.output.ray_cells import RayCells
from rls_addon.core.scan.frame import RayRecord


def rays_of(rng, moving):
    az = np.repeat(np.linspace(-math.pi, math.pi, 720, endpoint=False), 16)
    el = np.tile(np.radians(np.linspace(-25, 15, 16)), 720)
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
    times = np.linspace(0, 0.1, len(dirs))
    origins = (np.array([[0.0, 0.0, 2.0]]) if not moving
               else np.c_[times * 15.0, times * 3.0, np.full(len(times), 2.0)])
    obj = np.full(len(dirs), -1, np.int32)
    return RayRecord(origins, dirs, times, obj, np.full(len(dirs), np.inf),
                     np.zeros(0, np.int64), [])


@pytest.mark.parametrize("moving", [False, True])
def test_every_boxs_runs_hold_each_ray_near_it_once(moving):
    rng = np.random.default_rng(21 + moving)
    rays = rays_of(rng, moving)
    cells = RayCells(rays)
    n = 60
    centres = rng.uniform([-40, -40, -3], [40, 40, 10], (n, 3))
    centres[:6] = [[-20.0, 0.01, 2.0], [-20.0, -0.01, 2.0],  # across the seam (-pi / pi)
                   [0.3, 0.0, 2.0], [0.5, 0.0, 1.0],          # holding the origins
                   [0.0, 0.0, 30.0], [30.0, 0.0, 1.0]]         # over the pole; far, small
    radii = rng.uniform(0.5, 5.0, n)
    radii[5] = 1.0
    box, lo, hi = cells.segments(centres, radii)  # (no extents: whole spheres)
    assert np.all(hi > lo) and np.all(np.diff(box) >= 0)
    o = rays.origins if len(rays.origins) > 1 else np.repeat(rays.origins, len(rays.dirs), 0)
    for j in range(n):
        mine = np.concatenate([np.zeros(0, np.int64)] + [
            cells.cells.order[a:b] for a, b in zip(lo[box == j], hi[box == j])])
        assert len(np.unique(mine)) == len(mine), j  # each ray once
        rel = centres[j] - o
        along = np.einsum("ij,ij->i", rel, rays.dirs)
        perp2 = np.einsum("ij,ij->i", rel, rel) - along ** 2
        near = np.nonzero((along + radii[j] >= 0) & (perp2 <= radii[j] ** 2))[0]
        assert np.all(np.isin(near, mine)), j
        if j == 5:
            assert 0 < len(near) and len(mine) < len(rays.dirs) / 50
    assert np.count_nonzero(box == 2) and hi[box == 2].max() - lo[box == 2].min() > 0


def test_every_directions_rays_at_once_are_its_own():
    rng = np.random.default_rng(4)
    cells = RayCells(rays_of(rng, False))
    vs = np.r_[rng.normal(size=(40, 3)), [[0.0, 0.0, 1.0], [-1.0, 1e-4, 0.0]]]
    angles = np.r_[rng.uniform(0.005, 0.5, 40), [0.1, 0.05]]
    owner, ray = cells.within_many(vs, angles)
    for j, (v, a) in enumerate(zip(vs, angles)):
        assert np.sort(ray[owner == j]).tolist() == cells.within(v, a).tolist(), j
