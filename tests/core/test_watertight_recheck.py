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
