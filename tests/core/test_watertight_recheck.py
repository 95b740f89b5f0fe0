"""The watertight wrapper's re-check of misses (``casting/watertight.py``): which rays it
lets through to the hull cast. A ray to the open sky that passes over every hull box is
answered without one; every ray that enters some hull box is let through."""

import numpy as np
import pytest

from rls_addon.core.casting import embree
from rls_addon.core.device.presets import get_preset
from rls_addon.core.world.bodies import PreparedScene

from .scenes import open_sky, rays_entering_boxes

@pytest.mark.slow  # the brute-force oracle tests 115,200 rays against every hull box
def test_sky_rays_are_not_rechecked():
    """From 4 m above the ground every ray to the sky passes over the boxes (3 m at
    most): the re-check answers them all without a hull cast."""
    preset = get_preset("hesai_pandar64")
    origin = np.array([0.3, -0.2, 4.0])
    scene = PreparedScene(open_sky(), origin, preset.range.max_m, embree.EmbreeCaster)
    w = scene.caster
    dirs = preset.pattern().directions
    up = dirs[:, 2] > 0
    reach = w.may_reach_hull(origin - scene.centre, dirs, preset.range.max_m)
    assert up.sum() > 10_000 and not reach[up].any()
    # conservative: every ray that enters some hull box is let through
    enters = rays_entering_boxes(origin - scene.centre, dirs, w.box_lo, w.box_hi,
                                 preset.range.max_m)
    assert enters.sum() > 1000 and np.all(reach[enters])


def test_octant_boxes_are_the_union_of_the_boxes_ahead():
    """Per octant, the union of the hull boxes ahead of the origins along each of its
    axes (one octant at a time, as the table is defined)."""
    preset = get_preset("hesai_pandar64")
    scene = PreparedScene(open_sky(), np.array([0.3, -0.2, 4.0]), preset.range.max_m,
                          embree.EmbreeCaster)
    w = scene.caster
    for o in (np.array([[0.3, -0.2, 4.0]]), np.random.default_rng(3).normal(size=(50, 3)) * 20):
        boxes, has = w.octant_boxes(o)
        for code in range(8):
            neg = np.array([(code >> k) & 1 for k in range(3)], bool)
            sel = np.all(np.where(neg, w.box_lo < o.max(axis=0), w.box_hi > o.min(axis=0)),
                         axis=1)
            assert has[code] == sel.any()
            want = np.r_[w.box_lo[sel].min(axis=0), w.box_hi[sel].max(axis=0)] \
                if sel.any() else np.zeros(6)
            np.testing.assert_array_equal(boxes[code], want)


def test_the_hull_is_built_from_numpys_bounds_of_the_triangles():
    """The hull's boxes and the scene's extent (``vectors.triangle_bounds``,
    ``column_bounds``)
    are what numpy's min and max over ``vertices[triangles]`` give, float for float:
    random, degenerate (a repeated vertex, a point) and far-off triangles, groups and
    cells as a prepared scene uses them."""
    from rls_addon.core.casting import watertight
    from rls_addon.core.casting.numpy_caster import NumpyCaster
    from rls_addon.core.native import vectors

    rng = np.random.default_rng(40)
    v = rng.normal(size=(3000, 3)) * [50.0, 30.0, 4.0] + [1e4, -2e3, 0.0]
    v[::7] = -v[::7]
    t = rng.integers(0, len(v), (4000, 3))
    t[::11, 1] = t[::11, 0]
    t[::13] = t[::13, :1]
    v = np.vstack([v, [[1e6, -1e6, 1e6]]])  # a vertex of no triangle: not in the extent
    tv = v[t]
    lo, hi = vectors.triangle_bounds(v, t)
    assert lo.tobytes() == tv.min(axis=1).tobytes() and hi.tobytes() == tv.max(axis=1).tobytes()
    bad = v.copy()  # a NaN or infinite corner (clean_for_casting drops those triangles)
    bad[5:40:3] = [np.nan, np.inf, -np.inf]
    got = vectors.triangle_bounds(bad, t)
    assert np.array_equal(got[0], bad[t].min(axis=1), equal_nan=True)
    assert np.array_equal(got[1], bad[t].max(axis=1), equal_nan=True)
    groups = rng.integers(0, 5, len(t))
    got = watertight.cluster_boxes(v, t, groups, 7.5)
    # the reference: each triangle's box from numpy's reduction over its corners
    tmin, tmax = tv.min(axis=1), tv.max(axis=1)
    cells = np.floor((tmin + tmax) / 15.0).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    key = groups * int(np.prod(span)) + (cells[:, 0] * span[1] + cells[:, 1]) * span[2] \
        + cells[:, 2]
    want_lo = np.array([tmin[key == k].min(axis=0) for k in np.unique(key)])
    want_hi = np.array([tmax[key == k].max(axis=0) for k in np.unique(key)])
    assert np.array_equal(got[0], want_lo) and np.array_equal(got[1], want_hi)
    w = watertight.WatertightCaster(NumpyCaster, v, t, groups, 7.5)
    extent = float(np.linalg.norm(tv.reshape(-1, 3).max(0) - tv.reshape(-1, 3).min(0))) + 1.0
    assert w.extent == extent
    pad = 1e-5 * extent
    assert np.array_equal(w.box_lo, want_lo - pad) and np.array_equal(w.box_hi, want_hi + pad)
