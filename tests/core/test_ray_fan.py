"""Ground truth looks only at the rays and points toward each box (the per-box
reference's ``RayFan``, and ``RayCells``, the rays grouped by direction cell that every
box of a frame shares): the same visibility, points in the box and reference time as
looking at all of them, for still and moving sensors, boxes near and far, above, below
and around the azimuth seam."""

import math

import numpy as np
import pytest

from rls_addon.core.output.box_reference import RayFan, _facing, _inside, _visibility
from rls_addon.core.output.ray_cells import RayCells
from rls_addon.core.scan.frame import RayRecord


def spinning_rays(rng, n_az=720, moving=False):
    az = np.repeat(np.linspace(-math.pi, math.pi, n_az, endpoint=False), 16)
    el = np.tile(np.radians(np.linspace(-25, 15, 16)), n_az) + rng.normal(0, 1e-3, len(az))
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
    times = np.linspace(0, 0.1, len(dirs))
    origins = (np.array([[0.0, 0.0, 2.0]]) if not moving
               else np.c_[times * 15.0, np.zeros(len(times)), np.full(len(times), 2.0)])
    obj = rng.integers(-1, 4, len(dirs)).astype(np.int32)
    dist = np.where(obj >= 0, rng.uniform(1, 80, len(dirs)), np.inf)
    hit = np.nonzero(obj >= 0)[0]
    return RayRecord(origins, dirs, times, obj, dist, hit, [])


@pytest.mark.parametrize("moving", [False, True])
def test_a_fan_gives_what_all_rays_give(moving):
    rng = np.random.default_rng(7 if moving else 3)
    rays = spinning_rays(rng, moving=moving)
    world = rays.point_world(rays.dist[rays.point_ray])
    fan = RayFan(rays, world)
    cells = RayCells(rays)
    checked = 0
    for _ in range(300):
        centre = rng.uniform([-40, -40, -3], [40, 40, 12])
        if rng.random() < 0.1:  # right over the seam at -pi / pi, and very near
            centre = np.array([-rng.uniform(0.5, 30), rng.uniform(-0.3, 0.3), rng.uniform(0, 4)])
        yaw = rng.uniform(-math.pi, math.pi)
        pose = np.eye(4)
        pose[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                        [0, 0, 1]]
        pose[:3, 3] = centre
        size = rng.uniform([0.5, 0.5, 1.0], [10.0, 3.0, 4.0])
        assert _visibility(rays, 2, pose, size, 120.0, fan) == \
            _visibility(rays, 2, pose, size, 120.0)
        near = fan.points_near(centre, float(np.linalg.norm(size / 2 + 0.05)))
        inside = np.count_nonzero(_inside(world, pose, size, 0.05))
        assert np.count_nonzero(_inside(world[near], pose, size, 0.05)) == inside
        # the cells: every ray that crosses the box, and every point in it, is a candidate
        radius = float(np.linalg.norm(size / 2 + 0.05))
        _, cand = cells.pairs(cells.segments([centre], [radius]))
        assert len(np.unique(cand)) == len(cand)  # each ray once
        assert _visibility(rays, 2, pose, size, 120.0, _Only(fan, cand)) == \
            _visibility(rays, 2, pose, size, 120.0)
        mine = np.zeros(len(rays.dirs), bool)
        mine[cand] = True
        assert np.count_nonzero(_inside(world[mine[rays.point_ray]], pose, size, 0.05)) == inside
        best = fan.facing(centre)
        if best is not None:
            everything, _ = _facing(rays, centre, slice(None))
            assert best == everything
            checked += 1
    assert checked > 200  # the cones settled most of them


class _Only:
    """A ``RayFan`` stand-in that offers the given rays for every cone."""

    def __init__(self, fan, rays):
        self.rays, self._idx = fan.rays, np.sort(rays)

    def rays_near(self, centre, radius):
        return self._idx
