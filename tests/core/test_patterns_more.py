"""Pattern helpers shared by every family: the trace order for packet backends."""

import numpy as np


def test_trace_order_only_for_incoherent_firing_orders():
    """A Z-order permutation for patterns whose 16-ray packets point far apart (the M1's
    zones fire interleaved); spinning heads fire coherent columns and keep their order."""
    from rls_addon.core.device.patterns.base import z_order
    from rls_addon.core.device.presets import get_preset

    m1 = get_preset("robosense_m1").pattern()
    order = m1.trace_order
    assert order is not None and np.array_equal(np.sort(order), np.arange(len(m1)))
    assert get_preset("hesai_pandar64").pattern().trace_order is None
    # Z-order: the four quadrants of a grid come one after another.
    u, v = np.meshgrid(np.arange(4.0), np.arange(4.0))
    z = z_order(u.ravel(), v.ravel(), bits=2)
    first = np.stack([u.ravel()[z[:4]], v.ravel()[z[:4]]], 1)
    assert set(map(tuple, first)) == {(0, 0), (1, 0), (0, 1), (1, 1)}
