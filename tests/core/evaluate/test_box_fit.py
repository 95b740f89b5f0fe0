"""box_fit: oriented rectangles of many clusters at once, and vehicle-sized placements."""

import numpy as np
import pytest

from rls_addon.core.evaluate.detector.box_fit import (best_placement, fit_rectangles, inside_rectangle,
                                             rectangle_corners, rectangles_along)


def outline(cx, cy, length, width, yaw, sides=(0, 1, 2, 3), step=0.05, seed=0):
    """Points along the chosen sides of a rectangle (0: +u, 1: +v, 2: -u, 3: -v), with 1 cm
    noise."""
    rng = np.random.default_rng(seed)
    c = rectangle_corners(np.array([[cx, cy, length, width, yaw]]))[0]
    pts = []
    for k in sides:
        a, b = c[k], c[(k + 1) % 4]
        n = max(int(np.linalg.norm(b - a) / step), 2)
        t = np.linspace(0, 1, n)[:, None]
        pts.append(a + t * (b - a))
    p = np.concatenate(pts)
    return p + rng.normal(0, 0.01, p.shape)


# The closeness criterion counts points within d0 = 0.1 m of an edge as on it, so headings
# within about 1.3 degrees of a 4.5 m side score alike; with 1 cm noise on the extremes
# that bounds the extents to about 0.1 m.
YAW_TOL = np.radians(1.5)
SIZE_TOL = 0.1


def half_turn(a, b):
    return abs(np.mod(a - b + np.pi / 2, np.pi) - np.pi / 2)


@pytest.mark.parametrize("criterion", ["closeness", "area"])
def test_many_rectangles_at_once(criterion):
    truth = [(3.0, 4.0, 4.5, 1.8, 0.3), (-10.0, 2.0, 4.0, 1.7, -1.2), (20.0, -5.0, 8.0, 2.5, 2.0)]
    parts = [outline(*t, seed=k) for k, t in enumerate(truth)]
    rect = fit_rectangles(np.concatenate(parts), [len(p) for p in parts], criterion)
    for r, t in zip(rect, truth):
        assert np.allclose(r[:2], t[:2], atol=0.05)
        assert np.allclose(r[2:4], t[2:4], atol=SIZE_TOL)
        assert half_turn(r[4], t[4]) < YAW_TOL


def test_an_l_shape_gives_the_heading_and_both_extents():
    pts = outline(5.0, 2.0, 4.6, 1.9, 0.7, sides=(2, 3))  # two sides seen from one corner
    r = fit_rectangles(pts, [len(pts)])[0]
    assert np.allclose(r[:2], (5.0, 2.0), atol=0.05)
    assert np.allclose(r[2:4], (4.6, 1.9), atol=SIZE_TOL)
    assert half_turn(r[4], 0.7) < YAW_TOL


def test_extents_along_given_headings_and_length_is_the_longer_side():
    pts = outline(0.0, 0.0, 4.0, 2.0, 0.0)
    r = rectangles_along(pts, [len(pts)], [np.pi / 2])[0]  # asked across: swapped back
    assert np.allclose(r[2:4], (4.0, 2.0), atol=0.05)
    assert half_turn(r[4], 0.0) < 1e-9


def test_best_placement_finds_one_car_of_two_crossing():
    a = outline(0.0, 0.0, 4.5, 1.8, 0.0, step=0.1)
    b = outline(1.2, 1.0, 4.5, 1.8, np.pi / 2, step=0.1)
    fill_a = np.stack(np.meshgrid(np.arange(-2.2, 2.25, 0.15), np.arange(-0.85, 0.9, 0.15)),
                      -1).reshape(-1, 2)  # a's roof seen: the denser car
    pts = np.concatenate([a, b, fill_a])
    covered, cx, cy, yaw = best_placement(pts, (4.5, 1.8))
    assert np.hypot(cx, cy) < 0.2 and half_turn(yaw, 0.0) < np.radians(5.0)
    assert inside_rectangle(fill_a, cx, cy, 4.5, 1.8, yaw, grow=0.1).all()


def test_single_points_and_no_groups():
    assert fit_rectangles(np.zeros((0, 2)), []).shape == (0, 5)
    r = fit_rectangles(np.array([[1.0, 2.0]]), [1])[0]
    assert np.allclose(r[:4], (1.0, 2.0, 0.0, 0.0))
