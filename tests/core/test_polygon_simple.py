"""A region's outline must be one loop that does not cross or touch itself: a crossing
outline has no one inside (its net area and its even-odd inside disagree), so it is
refused where outlines are validated (``as_polygon``), with where it crosses. Checked
against shapely (a test-only oracle: rls_addon never imports it)."""

import numpy as np
import pytest

from rls_addon.core.errors import RegionError
from rls_addon.core.metrics.infra import infra_lob_metrics
from rls_addon.core.metrics.polygon import as_polygon
from rls_addon.core.points import empty_points

from .external_tools import require_module

try:  # the oracle: required by the fixture below (a skip, or a failure under make test)
    from shapely.geometry import LinearRing, Point
except ImportError:
    LinearRing = Point = None


@pytest.fixture(autouse=True, scope="module")
def _shapely():
    require_module("shapely", "shapely==2.2.0")


def crossing(poly):
    """The message of ``as_polygon``'s crossing error, or None when it accepts."""
    try:
        as_polygon(poly)
    except RegionError as exc:
        assert str(exc).startswith("the region's outline crosses itself at ("), str(exc)
        return str(exc)
    return None


def test_the_review_case_is_refused_where_it_crosses():
    poly = [[-12, -12], [12, 12], [12, -12], [-12, 6]]
    pts = empty_points(1)
    with pytest.raises(RegionError) as err:
        infra_lob_metrics(pts, poly)
    assert str(err.value) == (
        "the region's outline crosses itself at (-1.71429, -1.71429): edge 1 (vertex 1 to 2) "
        "meets edge 3 (vertex 3 to 4); draw it as one loop that does not cross or touch "
        "itself")


def test_a_symmetric_bow_tie_is_refused_as_crossing_not_as_collinear():
    msg = crossing([[0, 0], [10, 10], [10, 0], [0, 10]])
    assert msg.startswith("the region's outline crosses itself at (5, 5): ")


def test_touching_and_doubling_back_are_refused():
    # a vertex on another edge
    assert crossing([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]]).startswith(
        "the region's outline crosses itself at (2, 0): ")
    # an edge that runs back along the one before it (a spike)
    assert crossing([[0, 0], [4, 0], [4, 4], [4, 2], [0, 4]]) is not None
    # two vertices at one place, apart in the list (a figure eight)
    assert crossing([[0, 0], [2, 2], [4, 0], [4, 4], [2, 2], [0, 4]]) is not None


def test_simple_outlines_pass_as_before():
    for poly in ([[0, 0], [20, 0], [20, 30], [0, 30]],
                 [[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]],   # an L
                 [[0, 0], [1, 0], [2, 0], [2, 2], [0, 2]],           # straight on at a vertex
                 [[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]],           # explicitly closed
                 [[0, 0], [4, 0], [4, 0], [4, 4], [0, 4]]):          # a repeated vertex
        got = as_polygon(poly)
        assert np.array_equal(got, np.asarray(poly, float)[:len(got)])
    with pytest.raises(RegionError, match="collinear or repeated"):
        as_polygon([[0, 0], [1, 1], [2, 2]])


def random_polygons(rng, count):
    """Simple (star-shaped) and random-order outlines, with float and small-integer
    vertices (integers meet exactly: touching, collinear, overlapping edges)."""
    for k in range(count):
        m = int(rng.integers(3, 12))
        kind = k % 4
        if kind == 0:  # star-shaped around the origin: simple
            a = np.sort(rng.uniform(0, 2 * np.pi, m))
            r = rng.uniform(1, 10, m)
            yield np.c_[r * np.cos(a), r * np.sin(a)]
        elif kind == 1:  # random order of random points: mostly crossing
            yield rng.uniform(-10, 10, (m, 2))
        else:  # distinct points of a small grid, in random order
            grid = np.array([(x, y) for x in range(4) for y in range(4)], float)
            yield grid[rng.choice(len(grid), size=min(m, 8), replace=False)]


def test_random_outlines_are_refused_exactly_when_shapely_says_they_are_not_simple():
    rng = np.random.default_rng(11)
    seen = {True: 0, False: 0}
    for poly in random_polygons(rng, 3000):
        if np.linalg.matrix_rank(poly - poly[0]) < 2:
            continue  # all on one line: refused as collinear, not as crossing
        simple = LinearRing(poly).is_simple
        msg = crossing(poly)
        assert (msg is None) == simple, (poly.tolist(), msg)
        seen[simple] += 1
        if msg is not None:  # the place named lies on the outline twice
            xy = np.array([float(v) for v in msg.split("(")[1].split(")")[0].split(",")])
            assert LinearRing(poly).distance(Point(xy)) <= 1e-4
    assert seen[True] > 500 and seen[False] > 500
