"""The arc of directions in which a region lies, seen from a point
(``polygon.polygon_arc``, ``in_arc``): every half-line that crosses the
polygon is kept, and those clearly outside the arc are not."""

import numpy as np
import pytest

from rls_addon.core.metrics.polygon import ARC_MARGIN_RAD, in_arc, polygon_arc


def toward_polygon(poly, origin, directions):
    """The directions whose half-line may cross the polygon, as the study asks."""
    return in_arc(polygon_arc(poly, origin), directions)


SQUARE = np.array([(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)])
# a C shape round the origin's side (opening to +x): it spans more than half a turn
C_SHAPE = np.array([(-10, -10), (10, -10), (10, -8), (-8, -8), (-8, 8), (10, 8), (10, 10),
                    (-10, 10)], float)


def _crosses(poly, origin, d):
    """Exact: does the half-line from origin along d (xy) meet the polygon's outline
    (it starts outside, so it enters the polygon where it meets it)?"""
    a, b = poly, np.roll(poly, -1, axis=0)
    e = b - a
    w = a - origin
    den = d[0] * e[:, 1] - d[1] * e[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den   # along the half-line
        u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den         # along the edge
    return bool(np.any((den != 0) & (t > 0) & (u >= 0) & (u <= 1)))


@pytest.mark.parametrize("poly, origin, extent_deg", [
    (SQUARE, (40.0, 0.0), 2 * np.degrees(np.arctan2(20, 20))),     # facing a side: 90 deg
    (SQUARE, (40.0, 40.0), 2 * np.degrees(np.arctan2(20, 40))),    # past a corner
    (SQUARE, (25.0, -3.0), None),                                  # close: checked below
    (C_SHAPE, (0.0, 0.0), None),                                   # inside the C's mouth
])
def test_the_arc_holds_every_direction_that_crosses_the_region(poly, origin, extent_deg):
    origin = np.array(origin)
    arc = polygon_arc(poly, origin)
    assert arc is not None
    if extent_deg is not None:
        assert np.degrees(arc[1]) == pytest.approx(extent_deg + np.degrees(2 * ARC_MARGIN_RAD))
    az = np.linspace(-np.pi, np.pi, 3601)
    d = np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], 1)
    kept = np.zeros(len(d), bool)
    kept[toward_polygon(poly, origin, d)] = True
    crosses = np.array([_crosses(poly, origin, u[:2]) for u in d])
    assert crosses.any() and not crosses.all()
    assert np.all(kept[crosses])                  # nothing that crosses is dropped
    # and what is kept lies within the margin of something that crosses
    near = np.convolve(crosses, np.ones(5), "same") > 0
    assert np.all(near[kept])


def test_the_c_shape_spans_more_than_half_a_turn():
    start, extent = polygon_arc(C_SHAPE, (0.0, 0.0))
    assert extent > np.pi


@pytest.mark.parametrize("origin", [(0.0, 0.0), (20.0, 5.0), (20.0, 20.0), (-19.9, 3.0)])
def test_inside_or_on_the_outline_every_direction_is_kept(origin):
    assert polygon_arc(SQUARE, origin) is None
    assert toward_polygon(SQUARE, origin, np.eye(3)) is None


def test_a_direction_straight_up_or_down_is_kept():
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    # from (40, 0) the square lies towards -x
    np.testing.assert_array_equal(toward_polygon(SQUARE, (40.0, 0.0), d), [0, 1, 2])


def test_an_outline_winding_round_the_point_keeps_everything():
    # a spiral strip going once and a half round the origin without containing it
    t = np.linspace(0, 3 * np.pi, 80)
    outer = np.stack([(10 + t) * np.cos(t), (10 + t) * np.sin(t)], 1)
    inner = np.stack([(8 + t) * np.cos(t), (8 + t) * np.sin(t)], 1)[::-1]
    spiral = np.concatenate([outer, inner])
    assert polygon_arc(spiral, (0.0, 0.0)) is None
