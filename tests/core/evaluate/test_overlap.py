"""Rotated-box overlap: analytic cases, degenerate geometry, and every pair of thousands
against shapely polygons (shapely is the test's oracle only; core code does not use it,
and the oracle tests skip where it is not installed, or fail under RLS_REQUIRE_TOOLS=1)."""

import math

import numpy as np
import pytest
from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.overlap import (
    bev_corners,
    bev_intersection,
    bev_intersection_paired,
    bev_iou,
    iou,
    iou_3d,
    iou_at,
    iou_paired,
)
from tests.core.external_tools import require_module


def box(x=0.0, y=0.0, z=0.0, length=1.0, width=1.0, height=1.0, yaw=0.0):
    return np.array([[x, y, z, length, width, height, yaw]])


def shapely_areas(a, b):
    """Every pair's intersection area, by shapely."""
    Polygon = require_module("shapely.geometry", "shapely==2.2.0").Polygon
    pa = [Polygon(c) for c in bev_corners(a)]
    pb = [Polygon(c) for c in bev_corners(b)]
    return np.array([[p.intersection(q).area for q in pb] for p in pa])


def shapely_paired(a, b):
    Polygon = require_module("shapely.geometry", "shapely==2.2.0").Polygon
    return np.array([Polygon(p).intersection(Polygon(q)).area
                     for p, q in zip(bev_corners(a), bev_corners(b))])


def random_boxes(rng, n, spread=8.0):
    out = np.empty((n, 7))
    out[:, :2] = rng.uniform(-spread, spread, (n, 2))
    out[:, 2] = rng.uniform(-2, 2, n)
    out[:, 3:6] = rng.uniform(0.1, 20.0, (n, 3))
    out[:, 6] = rng.uniform(-2 * np.pi, 2 * np.pi, n)
    return out


def test_corners_counter_clockwise_from_front_right():
    got = bev_corners(box(x=10, y=5, length=4, width=2, yaw=np.pi / 2))[0]
    np.testing.assert_allclose(got, [[11, 7], [9, 7], [9, 3], [11, 3]], atol=1e-12)
    x, y = got[:, 0], got[:, 1]
    assert 0.5 * (x @ np.roll(y, -1) - y @ np.roll(x, -1)) == pytest.approx(8.0)


def test_identical_boxes_iou_one():
    b = box(3, -2, 1, 4.5, 1.8, 1.6, 0.7)
    assert bev_intersection(b, b)[0, 0] == pytest.approx(4.5 * 1.8, abs=1e-12)
    assert bev_iou(b, b)[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert iou_3d(b, b)[0, 0] == pytest.approx(1.0, abs=1e-12)


def test_box_turned_by_pi_is_the_same_rectangle():
    a = box(1e4, -1e4, 0, 4.0, 2.0, 1.5, 0.3)
    b = a.copy()
    b[0, 6] += np.pi
    assert bev_intersection(a, b)[0, 0] == 8.0
    assert iou_3d(a, b)[0, 0] == 1.0
    # Turned by a quarter with length and width swapped: the same rectangle too.
    c = box(1e4, -1e4, 0, 2.0, 4.0, 1.5, 0.3 + np.pi / 2)
    assert bev_iou(a, c)[0, 0] == pytest.approx(1.0, abs=1e-12)


def test_disjoint_and_touching_give_zero():
    a = box(length=2, width=2)
    assert bev_intersection(a, box(x=10, length=2, width=2))[0, 0] == 0.0
    # Sharing an edge, sharing a corner, circles touching but squares not.
    assert bev_intersection(a, box(x=2, length=2, width=2))[0, 0] == 0.0
    assert bev_intersection(a, box(x=2, y=2, length=2, width=2))[0, 0] == 0.0
    assert bev_intersection(a, box(x=2.5, y=2.5, length=2, width=2, yaw=0.2))[0, 0] == 0.0
    # A diamond's corner on the square's edge.
    d = box(x=1 + math.sqrt(0.5), length=1, width=1, yaw=np.pi / 4)
    assert bev_intersection(a, d)[0, 0] == pytest.approx(0.0, abs=1e-15)
    # Apart in height: BEV overlap, no 3D overlap.
    assert bev_iou(a, box(z=1.0, length=2, width=2))[0, 0] == 1.0
    assert iou_3d(a, box(z=1.0, length=2, width=2))[0, 0] == 0.0


def test_square_and_the_same_square_turned_45_degrees():
    # The octagon left: the unit square minus four corner triangles of leg 1 - 1/sqrt2.
    a, b = box(), box(yaw=np.pi / 4)
    expected = 2 * (math.sqrt(2) - 1)
    assert bev_intersection(a, b)[0, 0] == pytest.approx(expected, abs=1e-14)
    assert bev_iou(a, b)[0, 0] == pytest.approx(expected / (2 - expected), abs=1e-14)


def test_nested_boxes_give_the_smaller_area():
    outer = box(0, 0, 0, 10, 6, 4, 0.4)
    inner = box(0.5, -0.3, 0.5, 2, 1, 1, -1.1)
    assert bev_intersection(outer, inner)[0, 0] == pytest.approx(2.0, abs=1e-13)
    assert bev_intersection(inner, outer)[0, 0] == pytest.approx(2.0, abs=1e-13)
    assert iou_3d(outer, inner)[0, 0] == pytest.approx(2.0 / 240.0, abs=1e-15)


def test_collinear_overlapping_edges():
    # Same bottom edge line, one box slid along it by 1 m: overlap 3 x 2.
    a = box(length=4, width=2, yaw=0.9)
    b = box(x=math.cos(0.9), y=math.sin(0.9), length=4, width=2, yaw=0.9)
    assert bev_intersection(a, b)[0, 0] == pytest.approx(6.0, abs=1e-12)
    assert bev_iou(a, b)[0, 0] == pytest.approx(3 / 5, abs=1e-12)
    # A half-width box along one long side.
    c = box(y=0.5, length=4, width=1)
    assert bev_intersection(box(length=4, width=2), c)[0, 0] == 4.0


def test_shift_along_the_length_gives_three_fifths():
    # 4 x 2 x 1.5 box moved 1 m along its heading: 3 x 2 shared of 8 + 8 - 6.
    yaw = -2.2
    gt = box(100, 200, 1, 4, 2, 1.5, yaw)
    det = box(100 + math.cos(yaw), 200 + math.sin(yaw), 1, 4, 2, 1.5, yaw)
    assert bev_iou(det, gt)[0, 0] == pytest.approx(0.6, abs=1e-12)
    assert iou_3d(det, gt)[0, 0] == pytest.approx(0.6, abs=1e-12)


def test_partial_vertical_overlap():
    # 2 x 2 x 2 boxes, one 0.5 m higher: 1.5 of 2 m shared -> 6 / (8 + 8 - 6).
    a = box(length=2, width=2, height=2)
    b = box(z=0.5, length=2, width=2, height=2)
    assert iou_3d(a, b)[0, 0] == pytest.approx(0.6, abs=1e-15)
    # Different heights and a BEV shift: BEV 1 x 2 = 2 m^2 shared, z [0,1] vs [0.5,3].
    a = box(z=0.5, length=2, width=2, height=1)
    b = box(x=1, z=1.75, length=2, width=2, height=2.5)
    inter = 2 * 0.5
    assert iou_3d(a, b)[0, 0] == pytest.approx(inter / (4 + 10 - inter), abs=1e-15)


def test_very_thin_boxes():
    # A 1 um wide sliver across a square: 2 m x 1e-6 m inside it.
    a = box(length=2, width=2)
    sliver = box(length=10, width=1e-6, yaw=0.0)
    assert bev_intersection(a, sliver)[0, 0] == pytest.approx(2e-6, rel=1e-9)
    sliver[0, 6] = np.pi / 4
    assert bev_intersection(a, sliver)[0, 0] == pytest.approx(2 * math.sqrt(2) * 1e-6,
                                                              rel=1e-6)


def test_every_random_pair_agrees_with_shapely():
    rng = np.random.default_rng(20240611)
    a, b = random_boxes(rng, 60), random_boxes(rng, 50)
    got = bev_intersection(a, b)
    ref = shapely_areas(a, b)
    assert (ref > 0).mean() > 0.4  # most pairs do overlap, so clipping is exercised
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    # The same pairs 10 km away: the answer does not move.
    offset = np.array([1.2e4, -0.9e4, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(bev_intersection(a + offset, b + offset), ref,
                               rtol=0, atol=1e-9)


def test_degenerate_pairs_agree_with_shapely():
    # Half-metre grids of centres and sizes, yaws in steps of 45 degrees: shared edge
    # lines, shared corners, touching, nested and identical boxes in quantity.
    rng = np.random.default_rng(7)
    n = 4000
    a, b = np.zeros((n, 7)), np.zeros((n, 7))
    for s in (a, b):
        s[:, :2] = rng.integers(-4, 5, (n, 2)) * 0.5
        s[:, 3:5] = rng.integers(1, 9, (n, 2)) * 0.5
        s[:, 5] = 1.0
        s[:, 6] = rng.integers(-8, 9, n) * np.pi / 4
    b[:200] = a[:200]                         # identical
    b[200:400] = a[200:400] + [0, 0, 0, 0, 0, 0, np.pi]   # turned by pi
    ref = shapely_paired(a, b)
    nested = np.abs(ref - np.minimum(a[:, 3] * a[:, 4], b[:, 3] * b[:, 4])) < 1e-12
    assert (ref == 0).sum() > 500 and nested[400:].sum() > 100
    np.testing.assert_allclose(bev_intersection_paired(a, b), ref, rtol=0, atol=1e-9)
    shift = rng.uniform(-1e4, 1e4, (n, 2))
    a[:, :2] += shift
    b[:, :2] += shift
    np.testing.assert_allclose(bev_intersection_paired(a, b), ref, rtol=0, atol=1e-9)


def test_paired_matches_the_matrix_diagonal():
    rng = np.random.default_rng(3)
    a, b = random_boxes(rng, 40, 5), random_boxes(rng, 40, 5)
    for kind in ("bev", "3d"):
        table = iou(a, b, kind)
        np.testing.assert_array_equal(iou_paired(a, b, kind), np.diag(table))
        i, j = np.array([0, 5, 5, 39]), np.array([3, 5, 0, 39])
        np.testing.assert_array_equal(iou_at(a, b, i, j, kind), table[i, j])


def test_shapes_and_bad_input():
    assert bev_iou(np.zeros((0, 7)), box()).shape == (0, 1)
    assert iou_3d(box(), np.zeros((0, 7))).shape == (1, 0)
    with pytest.raises(InputError, match=r"\(N, 7\)"):
        bev_iou(np.zeros((2, 5)), box())
    with pytest.raises(InputError, match="as many boxes"):
        iou_paired(box(), np.zeros((2, 7)))
    with pytest.raises(InputError, match="bev, 3d"):
        iou(box(), box(), kind="2d")


def test_200_by_200_is_symmetric():
    """A 200 x 200 matrix (its time is a benchmark's, not a test's): IoU(a, b) is
    IoU(b, a) transposed, every value in [0, 1]."""
    rng = np.random.default_rng(11)
    a, b = random_boxes(rng, 200, 60), random_boxes(rng, 200, 60)
    a[:, 3:5] = rng.uniform(0.5, 5, (200, 2))
    b[:, 3:5] = rng.uniform(0.5, 5, (200, 2))
    m = iou_3d(a, b)
    assert m.shape == (200, 200)
    np.testing.assert_allclose(m, iou_3d(b, a).T, atol=1e-9)
    assert np.all((m >= 0) & (m <= 1 + 1e-12))
