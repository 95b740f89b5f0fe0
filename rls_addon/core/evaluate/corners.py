"""Boxes from their eight corners, in OpenCOOD's corner order.

OpenCOOD (DerrickXuNu/OpenCOOD, ``opencood/utils/box_utils.py``:
``boxes_to_corners_3d``, ``create_bbx``) orders a box's corners by the template
(length, width, height halves along the box's own x, y, z)

    0 (+l, -w, -h)  1 (+l, +w, -h)  2 (-l, +w, -h)  3 (-l, -w, -h)
    4 (+l, -w, +h)  5 (+l, +w, +h)  6 (-l, +w, +h)  7 (-l, -w, +h)

so 3 -> 0 points along the length (the heading), 0 -> 1 across, 0 -> 4 up. The fit
takes each axis as the mean of its four parallel edges: the centre is the corners'
mean, the sizes the axes' lengths, the yaw that of the length axis (counter-clockwise
from x about z, in the corners' frame). It refuses corner sets that are no box: edges
that are not parallel and equal (the corners rebuilt from the fit miss the given ones
by more than ``TOLERANCE_M``), axes not at right angles, or a size of zero."""

import numpy as np

from ..errors import InputError

TEMPLATE = np.array([[1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, -1],
                     [1, -1, 1], [1, 1, 1], [-1, 1, 1], [-1, -1, 1]], np.float64)
TOLERANCE_M = 2e-3      # corners saved as float32 far out still fit to well within this
SQUARE_COS = 2e-3       # |cos| between two axes: about 0.1 degree from a right angle


def fit_axes(corners):
    """(centre (N, 3), axes (N, 3, 3): rows length, width, height vectors) of (N, 8, 3)
    corners."""
    c = np.asarray(corners, np.float64)
    centre = c.mean(axis=1)
    # each axis vector is the mean of its four edges
    axes = np.einsum("ka,nkj->naj", TEMPLATE, c) / 4.0
    return centre, axes


def corners_to_boxes(corners, where="corners"):
    """(N, 7) boxes ``x y z length width height yaw`` of (N, 8, 3) corners in the
    frame they are given in; ``InputError`` naming ``where`` and the box for a corner
    set that is not a box."""
    c = np.asarray(corners, np.float64)
    if c.ndim != 3 or c.shape[1:] != (8, 3):
        raise InputError(f"{where}: corners have shape {c.shape}; expected (N, 8, 3)")
    if not np.isfinite(c).all():
        i = int(np.flatnonzero(~np.isfinite(c).all(axis=(1, 2)))[0])
        raise InputError(f"{where}: box {i} has a NaN or infinite corner")
    centre, axes = fit_axes(c)
    size = np.linalg.norm(axes, axis=2)
    flat = (size <= 1e-9).any(axis=1)
    if flat.any():
        i = int(np.flatnonzero(flat)[0])
        raise InputError(f"{where}: box {i} has corners with a size of zero: "
                         f"{c[i].tolist()}")
    rebuilt = centre[:, None, :] + np.einsum("ka,naj->nkj", TEMPLATE / 2.0, axes)
    miss = np.abs(rebuilt - c).max(axis=(1, 2))
    unit = axes / size[:, :, None]
    cos = np.abs(np.stack([np.einsum("nj,nj->n", unit[:, a], unit[:, b])
                           for a, b in ((0, 1), (0, 2), (1, 2))], 1)).max(axis=1)
    bad = (miss > TOLERANCE_M) | (cos > SQUARE_COS)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{where}: the 8 corners of box {i} are not a box (edges not "
                         f"parallel and equal within {TOLERANCE_M * 1000:g} mm, or not "
                         f"square: off by {miss[i] * 1000:.1f} mm, cos {cos[i]:.4f}); "
                         "expected OpenCOOD's corner order (box_utils.boxes_to_corners_3d)")
    yaw = np.arctan2(axes[:, 0, 1], axes[:, 0, 0])
    return np.concatenate([centre, size, yaw[:, None]], axis=1)


def boxes_to_corners(boxes):
    """(N, 8, 3) corners, in OpenCOOD's order, of upright (N, 7) boxes."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    local = TEMPLATE[None] * b[:, None, 3:6] / 2.0
    c, s = np.cos(b[:, 6])[:, None], np.sin(b[:, 6])[:, None]
    x = local[..., 0] * c - local[..., 1] * s
    y = local[..., 0] * s + local[..., 1] * c
    return np.stack([x, y, local[..., 2]], axis=-1) + b[:, None, :3]


__all__ = ["TEMPLATE", "boxes_to_corners", "corners_to_boxes", "fit_axes"]
