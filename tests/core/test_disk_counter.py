"""The study's disk counter against a brute-force test of every (point, disk) pair and
against the reference ``metrics.count_in_disks``: the same integer counts for random
points, points on the circles (in or out by a rounding, and exactly on them), on the
grid's cell borders, far from the origin, beyond the grid, and with no points, a
coarser grid or no grid at all. Every test runs twice: with the compiled counts
(native/c/disks.c) and with their numpy reference (``DiskCounter.counts_numpy``)."""

import numpy as np
import pytest

from rls_addon.core.metrics import disk_counter
from rls_addon.core.metrics.disk_counter import DiskCounter
from rls_addon.core.metrics.infra import count_in_disks
from tests.core.built import require_built


@pytest.fixture(autouse=True, params=["compiled", "numpy"])
def path(request, monkeypatch):
    """Each test with the compiled counts (which must be built: make test builds them)
    and with the numpy reference."""
    if request.param == "compiled":
        require_built(disk_counter.KERNEL)
    monkeypatch.setattr(disk_counter, "compiled", request.param == "compiled")
    return request.param


def brute_force(xy, centres, r):
    """Every (point, disk) pair tested with count_in_disks' comparison."""
    xy, centres = np.asarray(xy, np.float64), np.asarray(centres, np.float64)
    out = np.zeros(len(centres), np.int64)
    r2 = float(r) * float(r)
    for a in range(0, len(centres), 200):
        c = centres[a:a + 200]
        ddx = xy[None, :, 0] - c[:, None, 0]
        ddy = xy[None, :, 1] - c[:, None, 1]
        with np.errstate(over="ignore"):
            out[a:a + 200] = np.count_nonzero(ddx * ddx + ddy * ddy <= r2, axis=1)
    return out


def awkward_points(centres, r, rng, n=20_000, k=disk_counter.CELLS_PER_RADIUS):
    """Uniform points, points computed to lie on the circles (in or out by a rounding),
    points on the counter's cell borders, and points at the centres."""
    lo, hi = centres.min(axis=0) - 2 * r, centres.max(axis=0) + 2 * r
    uniform = rng.uniform(lo, hi, (n, 2))
    pick = centres[rng.integers(0, len(centres), n // 2)]
    a = rng.uniform(0, 2 * np.pi, n // 2)
    on_circle = pick + r * np.c_[np.cos(a), np.sin(a)]
    axis = pick + r * np.array([[1.0, 0.0], [0.0, -1.0], [-1.0, 0.0], [0.0, 1.0]])[
        rng.integers(0, 4, n // 2)]
    counter = DiskCounter(centres, r, k)
    borders = counter.lo + counter.h * rng.integers(0, max(counter.nx, counter.ny),
                                                    (n // 4, 2))
    return np.concatenate([uniform, on_circle, axis, borders, centres])


def assert_counts(xy, centres, r, k=disk_counter.CELLS_PER_RADIUS):
    want = brute_force(xy, centres, r)
    got = DiskCounter(centres, r, k).counts(xy)
    assert got.dtype == np.int64 and np.array_equal(got, want)
    assert np.array_equal(count_in_disks(xy, centres, r), want)
    return want


@pytest.mark.parametrize("offset", [0.0, 1e5, -3.7e6])
@pytest.mark.parametrize("r, k", [(0.7, 1), (0.7, 2), (0.7, 4), (1.3, 3), (0.05, 5)])
def test_counts_equal_brute_force_and_the_reference(offset, r, k):
    rng = np.random.default_rng(int(r * 100) + k)
    centres = rng.uniform(-15, 15, (800, 2)) + offset
    xy = awkward_points(centres, r, rng, k=k)
    want = assert_counts(xy, centres, r, k)
    assert want.sum() > len(centres)  # the points do land in disks


@pytest.mark.parametrize("k", [1, 2, 3, 4, 8])
def test_points_exactly_on_the_circles_and_the_cell_borders_count(k):
    """Dyadic centres, radius 5/8 and offsets (3/8, 4/8): every (dx, dy) and dx^2 + dy^2
    is exact, so these points are exactly on their circles (counted: the test is <=);
    with k = 1, 2, 4, 8 the cell borders (multiples of r / k from the grid's corner)
    fall on such points too. Points a rounding inside or outside count as the pair
    test says."""
    rng = np.random.default_rng(k)
    r = 0.625
    centres = rng.integers(-64, 64, (300, 2)) / 8.0
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    legs = np.array([[0.375, 0.5], [0.5, 0.375], [0.625, 0.0], [0.0, 0.625]])
    on = (centres[:, None, None, :] + signs[None, :, None, :] * legs[None, None, :, :]
          ).reshape(-1, 2)
    nudged = np.concatenate([np.nextafter(on, on + 1.0), np.nextafter(on, on - 1.0)])
    xy = np.concatenate([on, nudged, centres])
    dd = ((on.reshape(len(centres), -1, 2) - centres[:, None]) ** 2).sum(-1)
    assert (dd == r * r).all()  # exactly on the circle
    want = assert_counts(xy, centres, r, k)
    assert (want >= 16).all()  # each disk holds at least its own 16 boundary points


def test_the_bench_disks_with_many_points():
    """The study's default: 6,000 disks of 0.7 m in a 40 m square, 14k points."""
    rng = np.random.default_rng(11)
    centres = rng.uniform(-19.3, 19.3, (6000, 2))
    xy = np.concatenate([rng.uniform(-20, 20, (12_000, 2)),
                         awkward_points(centres[:500], 0.7, rng, 1000)])
    assert_counts(xy, centres, 0.7)


def test_inside_runs_and_edge_cells_cover_each_disk_once():
    """Per disk: the inside runs' cells are wholly within the radius, the edge cells and
    the inside cells do not overlap, and together they hold every cell the disk
    touches."""
    rng = np.random.default_rng(2)
    centres = rng.uniform(-5, 5, (50, 2))
    r = 1.0
    c = DiskCounter(centres, r, 4)
    assert len(c.edge_disk) and (c.span_hi > c.span_lo).any()
    assert (c.span_hi >= c.span_lo).all()
    edge_cell = np.repeat(np.arange(c.nx * c.ny), c.edge_count)
    for d in range(len(centres)):
        inside = {int(i) for lo, hi in zip(c.span_lo[:, d], c.span_hi[:, d])
                  for i in range(lo, hi)}
        edge = set(edge_cell[c.edge_disk == d].tolist())
        assert not inside & edge
        for cell in inside:  # the four corners are within the radius
            ix, iy = cell % c.nx, cell // c.nx
            corners = c.lo + c.h * np.array([[ix, iy], [ix + 1, iy], [ix, iy + 1],
                                             [ix + 1, iy + 1]])
            assert (np.linalg.norm(corners - centres[d], axis=1) <= r).all()
        # every cell whose nearest point is within the radius is inside or edge
        ix, iy = np.meshgrid(np.arange(c.nx), np.arange(c.ny))
        x0, y0 = c.lo[0] + ix * c.h, c.lo[1] + iy * c.h
        nx = np.clip(centres[d, 0], x0, x0 + c.h) - centres[d, 0]
        ny = np.clip(centres[d, 1], y0, y0 + c.h) - centres[d, 1]
        touched = set((iy * c.nx + ix)[nx * nx + ny * ny < r * r].tolist())
        assert touched <= inside | edge


def test_no_points_points_far_away_coarser_cells_and_the_fallback(monkeypatch):
    rng = np.random.default_rng(3)
    centres = rng.uniform(0, 10, (100, 2))
    c = DiskCounter(centres, 0.5)
    assert np.array_equal(c.counts(np.empty((0, 2))), np.zeros(100, np.int64))
    far = np.array([[1e4, 1e4], [-50.0, 3.0], [5.0, -1e9], [1e300, -1e300]])
    assert np.array_equal(c.counts(far), np.zeros(100, np.int64))
    odd = np.array([[np.nan, 5.0], [5.0, np.nan], [np.inf, 5.0], [5.0, -np.inf]])
    assert np.array_equal(c.counts(np.concatenate([odd, centres])),
                          brute_force(centres, centres, 0.5))
    xy = np.concatenate([awkward_points(centres, 0.5, rng, 2000), far])
    want = brute_force(xy, centres, 0.5)
    assert np.array_equal(c.counts(xy), want)
    # a grid too large at 4 cells per radius takes larger cells
    monkeypatch.setattr(disk_counter, "MAX_CELLS", c.nx * c.ny - 1)
    coarser = DiskCounter(centres, 0.5)
    assert coarser.usable and coarser.k < c.k
    assert np.array_equal(coarser.counts(xy), want)
    # and none at all: the reference (whose grid spans the points: not to 1e300)
    monkeypatch.setattr(disk_counter, "MAX_CELLS", 10)
    small = DiskCounter(centres, 0.5)
    assert not small.usable
    assert np.array_equal(small.counts(xy[:-1]), want)


def test_input_layouts():
    """Non-contiguous, float32 and list input give the same counts."""
    rng = np.random.default_rng(4)
    centres = rng.uniform(0, 10, (200, 2))
    xy = awkward_points(centres, 0.7, rng, 3000)
    c = DiskCounter(centres, 0.7)
    want = brute_force(xy, centres, 0.7)
    assert np.array_equal(c.counts(np.asfortranarray(xy)), want)
    assert np.array_equal(c.counts(np.concatenate([xy, xy], axis=1)[:, 1:3][:, ::-1]), want)
    assert np.array_equal(c.counts(xy.tolist()), want)
    f32 = xy.astype(np.float32)
    assert np.array_equal(c.counts(f32), brute_force(f32.astype(np.float64), centres, 0.7))


def test_one_counter_over_many_calls_and_in_another_process():
    """A study counts every candidate with one counter: calls of growing and shrinking
    size give the reference's counts each time (the compiled path keeps its scratch
    between calls), and a counter sent to a worker (pickled) counts the same."""
    import pickle

    rng = np.random.default_rng(9)
    centres = rng.uniform(-10, 10, (300, 2))
    c = DiskCounter(centres, 0.7)
    for n in (10, 5000, 3, 20_000, 0, 700):
        xy = rng.uniform(-12, 12, (n, 2))
        assert np.array_equal(c.counts(xy), count_in_disks(xy, centres, 0.7)), n
    xy = rng.uniform(-12, 12, (4000, 2))
    assert np.array_equal(pickle.loads(pickle.dumps(c)).counts(xy),
                          count_in_disks(xy, centres, 0.7))
