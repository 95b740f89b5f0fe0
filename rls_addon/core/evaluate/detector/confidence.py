"""The confidence of a detected box, in [0, 1]: how much evidence its cluster holds.

``n / (n + 20)`` of its point count (a box of 20 points is half sure, of 180 nine tenths)
times ``0.5 + 0.5 * min(1, seen area / prior area)``: a cluster that covers its class's
whole footprint is worth more than a sliver grown to it. The AP's precision-recall curve
is ordered by it."""

import numpy as np


def confidence(points, area_share):
    """(G,) confidences of boxes of ``points`` (G,) returns covering ``area_share`` (G,)
    of their class's size prior."""
    points = np.asarray(points, np.float64)
    share = np.minimum(np.asarray(area_share, np.float64), 1.0)
    return np.clip(points / (points + 20.0) * (0.5 + 0.5 * share), 0.0, 1.0)
