"""The study's disk counter against the reference ``metrics.count_in_disks``: the same
integer counts for random points, points on the circles, on the grid's cell borders,
far from the origin, beyond the grid, and with no points or no grid at all."""

import numpy as np
import pytest

from rls_addon.core import disk_counter
from rls_addon.core.disk_counter import DiskCounter
from rls_addon.core.metrics import count_in_disks


def awkward_points(centres, r, rng, n=20_000):
    """Uniform points, points computed to lie on the circles (in or out by a rounding),
    points on the counter's cell borders, and points at the centres."""
    lo, hi = centres.min(axis=0) - 2 * r, centres.max(axis=0) + 2 * r
    uniform = rng.uniform(lo, hi, (n, 2))
    pick = centres[rng.integers(0, len(centres), n // 2)]
    a = rng.uniform(0, 2 * np.pi, n // 2)
    on_circle = pick + r * np.c_[np.cos(a), np.sin(a)]
    axis = pick + r * np.array([[1.0, 0.0], [0.0, -1.0], [-1.0, 0.0], [0.0, 1.0]])[
        rng.integers(0, 4, n // 2)]
    counter = DiskCounter(centres, r)
    borders = counter.lo + counter.h * rng.integers(0, 2 * max(counter.nx, counter.ny),
                                                    (n // 4, 2))
    return np.concatenate([uniform, on_circle, axis, borders, centres])


@pytest.mark.parametrize("offset", [0.0, 1e5, -3.7e6])
@pytest.mark.parametrize("r, k", [(0.7, 1), (0.7, 2), (1.3, 3), (0.05, 2)])
def test_counts_equal_the_reference(offset, r, k):
    rng = np.random.default_rng(int(r * 100) + k)
    centres = rng.uniform(-15, 15, (800, 2)) + offset
    xy = awkward_points(centres, r, rng)
    want = count_in_disks(xy, centres, r)
    got = DiskCounter(centres, r, k).counts(xy)
    assert got.dtype == want.dtype and np.array_equal(got, want)
    assert want.sum() > len(centres)  # the points do land in disks


def test_inside_cells_hold_only_points_within_the_radius():
    rng = np.random.default_rng(2)
    centres = rng.uniform(-5, 5, (50, 2))
    c = DiskCounter(centres, 1.0, 4)
    assert len(c.inside_cell) and len(c.edge_cell)
    # the four corners of every inside cell are within the radius of its disk
    ix, iy = c.inside_cell % c.nx, c.inside_cell // c.nx
    for dx in (0, 1):
        for dy in (0, 1):
            corner = c.lo + c.h * np.c_[ix + dx, iy + dy]
            assert (np.linalg.norm(corner - centres[c.inside_disk], axis=1) <= 1.0).all()


def test_no_points_points_far_away_and_the_fallback(monkeypatch):
    rng = np.random.default_rng(3)
    centres = rng.uniform(0, 10, (100, 2))
    c = DiskCounter(centres, 0.5)
    assert np.array_equal(c.counts(np.empty((0, 2))), np.zeros(100, np.int64))
    far = np.array([[1e4, 1e4], [-50.0, 3.0], [5.0, -1e9]])
    assert np.array_equal(c.counts(far), np.zeros(100, np.int64))
    xy = awkward_points(centres, 0.5, rng, 2000)
    monkeypatch.setattr(disk_counter, "MAX_CELLS", 10)
    small = DiskCounter(centres, 0.5)
    assert not small.usable
    assert np.array_equal(small.counts(xy), count_in_disks(xy, centres, 0.5))
