"""Boxing: an oriented box and a class for each cluster of foreground points.

The heading comes from the clustering (the L-shape fit of the cluster's columns,
``box_fit``); the extents are the points' own along it; the top is the highest point and
the bottom the lowest, or the ground when the lower part is hidden (more than 0.5 m
above it). The class is by size (``priors.classify``). A box whose visible extent is
partial is grown to the size of the class's type it most likely shows
(``priors.target_size``: the class's prior, or one of the scene's own types) away from
the sensors that saw it (the far
side is hidden by the object itself), or towards a sensor that saw it behind another
cluster (the occluder hides the near side). Each box's confidence is
``confidence.confidence``."""

import numpy as np

from ..detections import Boxes
from .box_fit import rectangles_along, wrap_half_turn
from .confidence import confidence
from .priors import classify, target_size


def boxes(xyz, which, groups, yaw, origins, frame, ground, priors, min_score=0.0):
    """``Boxes`` (world frame, all in ``frame``) of the point ``groups`` (index arrays
    into ``xyz`` (M, 3), seen by sensors ``which`` (M,), index into ``origins`` (S, 3))
    with headings ``yaw`` (G,), over ``ground`` (a ``GroundGrid``), classed and grown by
    ``priors`` ({label: ClassPrior}). Groups of no class, and boxes whose confidence is
    below ``min_score``, give no box."""
    n = len(groups)
    sizes = np.array([len(g) for g in groups], np.int64)
    idx = np.concatenate(groups)
    rect = rectangles_along(xyz[idx, :2], sizes, yaw)
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    z = xyz[idx, 2]
    top = np.maximum.reduceat(z, starts)
    low = np.minimum.reduceat(z, starts)
    floor = ground.height_at(rect[:, :2])
    height = top - floor
    label = classify(rect[:, 2], rect[:, 3], height, priors)
    keep = label > 0
    # which sensors saw each cluster: the side of the box each looks from
    seen_by = np.zeros((n, max(len(origins), 1)), bool)
    seen_by[np.repeat(np.arange(n), sizes), which[idx]] = True
    behind = occluded(xyz[idx, :2], which[idx], sizes, origins)
    box = np.zeros((n, 7))
    area_share = np.ones(n)
    for k in np.flatnonzero(keep):
        cx, cy, L, W, yk = rect[k]
        # the type is judged by what the points span (a body on wheels starts above the
        # ground: its types' heights are the body's)
        size = target_size(priors[label[k]], L, W, top[k] - low[k])
        eyes = origins[seen_by[k, :len(origins)], :2]
        cx, cy, L, W = grow(cx, cy, L, W, yk, max(size[:2]), min(size[:2]), eyes,
                            behind[k, seen_by[k, :len(origins)]])
        area_share[k] = min(1.0, rect[k, 2] * rect[k, 3] / (size[0] * size[1]))
        # bottom: the lowest point, or the ground when the lower part is hidden
        bottom = low[k]
        if bottom - floor[k] > 0.5:
            bottom = max(floor[k], top[k] - size[2])
        h = max(top[k] - bottom, 0.3)
        box[k] = (cx, cy, bottom + h / 2, L, W, h, wrap_half_turn(yk))
    score = confidence(sizes, area_share)
    sel = np.flatnonzero(keep & (score >= min_score))
    return Boxes(np.full(len(sel), frame), box[sel], label[sel], score[sel])


def grow(cx, cy, L, W, yaw, L0, W0, eyes, behind=None):
    """The rectangle grown to at least L0 x W0, each axis away from the sensors that saw
    it (a sensor sees an object's near side; its far side is hidden by the object
    itself), or towards a sensor that saw it behind another object (``behind``: the
    occluder hides the near side, the far side is what shows); along an axis whose both
    ends are seen (or neither), about its middle."""
    c, s = np.cos(yaw), np.sin(yaw)
    out = []
    for axis, (ext, want) in enumerate(((L, L0), (W, W0))):
        if ext >= want:
            out.append((0.0, ext))
            continue
        u = np.array([c, s]) if axis == 0 else np.array([-s, c])
        if len(eyes):
            pos = (eyes - (cx, cy)) @ u  # where each sensor is along this axis
            if behind is not None:
                pos = np.where(behind, -pos, pos)  # an occluded sensor sees the far side
            low_side = bool((pos < -ext / 2).any())
            high_side = bool((pos > ext / 2).any())
        else:
            low_side = high_side = False
        grow = want - ext
        if low_side and not high_side:  # the low end is the seen one: grow upwards
            shift = grow / 2
        elif high_side and not low_side:
            shift = -grow / 2
        else:
            shift = 0.0
        out.append((shift, want))
    (su, L), (sv, W) = out
    cx += su * c - sv * s
    cy += su * s + sv * c
    return cx, cy, L, W


def occluded(xy, which, sizes, origins, min_overlap=0.3):
    """(G, S) bool: group k is seen by sensor s behind another group: one whose azimuth
    interval from s (its points', seen by s) covers at least ``min_overlap`` of k's and
    whose nearest point is nearer to s. Such a group shows s its far side."""
    G, S = len(sizes), len(origins)
    out = np.zeros((G, S), bool)
    if G < 2:
        return out
    g = np.repeat(np.arange(G), sizes)
    for s_ in range(S):
        mine = which == s_
        if not mine.any():
            continue
        d = xy[mine] - origins[s_, :2]
        gk = g[mine]
        present = np.bincount(gk, minlength=G) > 0
        az = np.arctan2(d[:, 1], d[:, 0])
        r = np.hypot(d[:, 0], d[:, 1])
        # each group's interval about its mean direction (no wrap within an object)
        cx = np.bincount(gk, np.cos(az), G)
        cy = np.bincount(gk, np.sin(az), G)
        mid = np.arctan2(cy, cx)
        rel = np.angle(np.exp(1j * (az - mid[gk])))
        lo = np.full(G, np.inf)
        hi = np.full(G, -np.inf)
        rmin = np.full(G, np.inf)
        np.minimum.at(lo, gk, rel)
        np.maximum.at(hi, gk, rel)
        np.minimum.at(rmin, gk, r)
        shift = np.angle(np.exp(1j * (mid[None, :] - mid[:, None])))  # j's mid seen from k's
        jlo, jhi = lo[None, :] + shift, hi[None, :] + shift
        overlap = np.clip(np.minimum(hi[:, None], jhi) - np.maximum(lo[:, None], jlo), 0, None)
        span = np.maximum(hi - lo, 1e-9)[:, None]
        front = (overlap / span >= min_overlap) & (rmin[None, :] < rmin[:, None])
        front &= present[:, None] & present[None, :]
        np.fill_diagonal(front, False)
        out[:, s_] = front.any(axis=1)
    return out
