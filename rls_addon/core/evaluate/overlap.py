"""Exact overlap of rotated boxes: bird's-eye-view (BEV) intersection area, BEV IoU and
3D IoU, for every pair of two box sets or elementwise for two equal-length sets.

Boxes are (N, 7) float64 rows ``x y z length width height yaw`` in the world frame
(``detections.py``): ``z`` is the box centre, ``length`` lies along the heading, ``yaw``
turns counter-clockwise from +X about +Z. The BEV footprint of a box is the rectangle of
its length and width about its centre, turned by its yaw; its vertical extent is
``[z - height/2, z + height/2]``.

The BEV intersection is exact convex clipping, vectorised over all pairs (no Python loop
per pair): box ``a``'s rectangle is expressed in box ``b``'s own frame (``b``'s centre
subtracted before anything is turned, so 10 km world offsets cost no precision; the
relative yaw taken modulo pi, so a box turned by pi is the same rectangle to the last
bit), clipped to ``b``'s two axis-aligned slabs ``|u| <= length/2`` and ``|v| <=
width/2`` (Sutherland-Hodgman against two parallel sides at once, with a fixed vertex
count: see ``_slab``), and measured by the shoelace formula. Pairs whose circumscribed
circles do not meet (and in 3D, pairs apart in height) are not clipped: their overlap is
0. Touching edges or corners give 0; a box inside the other gives the smaller area.
Results lie in ``[0, min(area_a, area_b)]`` and agree with shapely to about 1e-14 m^2
(tests/core/evaluate/test_overlap.py).

IoU is ``intersection / (area_a + area_b - intersection)`` in BEV and ``(BEV intersection
x vertical overlap) / (volume_a + volume_b - intersection)`` in 3D; sizes must be positive
(``Boxes.validate`` checks)."""

import numpy as np

from ..errors import InputError

IOU_KINDS = ("bev", "3d")

# Local corner signs of a box, counter-clockwise: front-right, front-left, back-left,
# back-right (front is +length/2 along the heading, left is +width/2).
_CORNER_SIGNS = np.array([[1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]])


def _as_boxes(box, name):
    """(N, 7) float64 from an array-like or anything with a ``.box`` (a ``Boxes``)."""
    box = getattr(box, "box", box)
    try:
        box = np.asarray(box, np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: boxes must be numbers, rows of x y z length width "
                         "height yaw") from None
    if box.size == 0 or (box.ndim == 1 and box.size == 7):
        box = box.reshape(-1, 7)
    if box.ndim != 2 or box.shape[1] != 7:
        raise InputError(f"{name}: boxes must be an (N, 7) array of x y z length width "
                         f"height yaw, got shape {box.shape}")
    return box


def bev_corners(box):
    """(N, 4, 2) BEV corners of the (N, 7) boxes, counter-clockwise, starting front-right."""
    box = _as_boxes(box, "bev_corners")
    half = 0.5 * box[:, None, 3:5] * _CORNER_SIGNS           # (N, 4, 2) local offsets
    c, s = np.cos(box[:, 6])[:, None], np.sin(box[:, 6])[:, None]
    x = box[:, None, 0] + c * half[..., 0] - s * half[..., 1]
    y = box[:, None, 1] + s * half[..., 0] + c * half[..., 1]
    return np.stack([x, y], axis=-1)


def _next(x):
    """Each row's vertices shifted by one: the end of every edge (the rows are closed)."""
    return np.concatenate([x[:, 1:], x[:, :1]], axis=1)


def _limit(x, lo, hi):
    """Clamp ``x`` into [lo, hi] in place (np.clip's dispatch costs more than the work)."""
    np.maximum(x, lo, out=x)
    np.minimum(x, hi, out=x)


def _slab(u, v, half):
    """Clip every polygon to the slab ``|u| <= half`` (``half`` (P, 1)); ``u`` and ``v``
    (P, K) are its vertices' coordinates across and along the slab, in order, closed.

    Each edge gives two vertices: where it enters the slab and where it leaves (the
    parameters of its crossings of the two sides, sorted and limited to the edge), both
    with ``u`` clamped into the slab. An edge inside gives its start and end; one
    outside gives one or two points on the side it is beyond. A stretch of the outline
    outside the slab so becomes a walk along the side it left by (the slab's outside is
    two half-planes, so a stretch never passes from one side to the other without an
    edge crossing the slab, which gives its points). A walk along a straight line adds
    no area however it turns back, so the shoelace area of the result is that of the
    polygon's part in the slab, as Sutherland-Hodgman would leave it, with repeated and
    collinear vertices that add nothing. Returns (P, 2K) ``u`` and ``v``."""
    du = _next(u) - u
    dv = _next(v) - v
    with np.errstate(invalid="ignore", divide="ignore"):
        ta = (-half - u) / du
        tb = (half - u) / du
    flat = du == 0  # parallel to the sides: wholly in or out, the clamp settles it
    t_in = np.minimum(ta, tb)
    t_out = np.maximum(ta, tb)
    t_in[flat] = 0.0
    t_out[flat] = 1.0
    _limit(t_in, 0.0, 1.0)
    _limit(t_out, 0.0, 1.0)
    p, k = u.shape
    out_u = np.empty((p, k, 2))
    out_v = np.empty((p, k, 2))
    out_u[..., 0] = u + t_in * du
    out_u[..., 1] = u + t_out * du
    out_v[..., 0] = v + t_in * dv
    out_v[..., 1] = v + t_out * dv
    half = half[:, :, None]
    _limit(out_u, -half, half)
    return out_u.reshape(p, 2 * k), out_v.reshape(p, 2 * k)


def _shoelace(x, y):
    """(P,) signed area of each row's closed polygon (P, K)."""
    return 0.5 * (x * _next(y) - y * _next(x)).sum(axis=1)


def _clip_area(a, b):
    """(P,) BEV intersection area of row i of ``a`` with row i of ``b`` (both (P, 7))."""
    # a's centre and heading in b's frame (b's centre subtracted before anything is
    # turned); a rectangle turned by pi is the same one, so the relative yaw is taken
    # in [-pi/2, pi/2).
    dx = a[:, 0] - b[:, 0]
    dy = a[:, 1] - b[:, 1]
    cb, sb = np.cos(b[:, 6]), np.sin(b[:, 6])
    ux = cb * dx + sb * dy
    uy = cb * dy - sb * dx
    rel = np.remainder(a[:, 6] - b[:, 6] + 0.5 * np.pi, np.pi) - 0.5 * np.pi
    cr, sr = np.cos(rel)[:, None], np.sin(rel)[:, None]
    hx = 0.5 * a[:, None, 3] * _CORNER_SIGNS[:, 0]
    hy = 0.5 * a[:, None, 4] * _CORNER_SIGNS[:, 1]
    vx = ux[:, None] + cr * hx - sr * hy
    vy = uy[:, None] + sr * hx + cr * hy
    vx, vy = _slab(vx, vy, 0.5 * b[:, 3:4])
    vy, vx = _slab(vy, vx, 0.5 * b[:, 4:5])
    inter = _shoelace(vx, vy)
    _limit(inter, 0.0, np.minimum(a[:, 3] * a[:, 4], b[:, 3] * b[:, 4]))
    return inter


def _reach(box):
    """Radius of each box's circumscribed circle in BEV."""
    return 0.5 * np.hypot(box[:, 3], box[:, 4])


def _z_overlap(a, b):
    """Length of the overlap of the boxes' vertical extents (0 when apart), broadcast."""
    top = np.minimum(a[..., 2] + 0.5 * a[..., 5], b[..., 2] + 0.5 * b[..., 5])
    bottom = np.maximum(a[..., 2] - 0.5 * a[..., 5], b[..., 2] - 0.5 * b[..., 5])
    return np.maximum(top - bottom, 0.0)


def _overlap(a, b, kind):
    """(P,) BEV intersection ('area'), BEV IoU ('bev') or 3D IoU ('3d') of row i of
    ``a`` with row i of ``b``; pairs that cannot meet are not clipped."""
    out = np.zeros(len(a))
    dx = a[:, 0] - b[:, 0]
    dy = a[:, 1] - b[:, 1]
    reach = _reach(a) + _reach(b)
    # Circumscribed circles that do not meet cannot overlap (the margin keeps pairs
    # whose circles just touch, where rounding could decide).
    near = dx * dx + dy * dy <= reach * reach * (1 + 1e-9)
    if kind == "3d":
        height = _z_overlap(a, b)
        near &= height > 0
    idx = np.flatnonzero(near)
    if not len(idx):
        return out
    a, b = a[idx], b[idx]
    inter = _clip_area(a, b)
    if kind == "area":
        out[idx] = inter
    elif kind == "bev":
        out[idx] = inter / (a[:, 3] * a[:, 4] + b[:, 3] * b[:, 4] - inter)
    else:
        volume = inter * height[idx]
        out[idx] = volume / (a[:, 3] * a[:, 4] * a[:, 5] + b[:, 3] * b[:, 4] * b[:, 5]
                             - volume)
    return out


def _all_pairs(a, b, kind):
    """(N, M) ``_overlap`` of every box of ``a`` with every box of ``b``: only pairs that
    can meet are gathered and clipped."""
    out = np.zeros((len(a), len(b)))
    if not (len(a) and len(b)):
        return out
    dx = a[:, None, 0] - b[None, :, 0]
    dy = a[:, None, 1] - b[None, :, 1]
    reach = _reach(a)[:, None] + _reach(b)[None, :]
    near = dx * dx + dy * dy <= reach * reach * (1 + 1e-9)
    if kind == "3d":
        near &= _z_overlap(a[:, None, :], b[None, :, :]) > 0
    i, j = np.nonzero(near)
    out[i, j] = _overlap(a[i], b[j], kind)
    return out


def _check_kind(kind):
    if kind not in IOU_KINDS:
        raise InputError(f"unknown overlap kind '{kind}': choose one of "
                         + ", ".join(IOU_KINDS))


def _paired(a, b):
    a, b = _as_boxes(a, "a"), _as_boxes(b, "b")
    if len(a) != len(b):
        raise InputError(f"paired overlap needs as many boxes on each side, got {len(a)} "
                         f"and {len(b)}")
    return a, b


def bev_intersection(a, b):
    """(N, M) BEV intersection area (m^2) of every box of ``a`` (N, 7) with every box of
    ``b`` (M, 7)."""
    return _all_pairs(_as_boxes(a, "a"), _as_boxes(b, "b"), "area")


def bev_intersection_paired(a, b):
    """(N,) BEV intersection area (m^2) of box i of ``a`` with box i of ``b``, both (N, 7)."""
    return _overlap(*_paired(a, b), "area")


def iou(a, b, kind="3d"):
    """(N, M) IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7); ``kind`` is
    'bev' or '3d'."""
    _check_kind(kind)
    return _all_pairs(_as_boxes(a, "a"), _as_boxes(b, "b"), kind)


def iou_paired(a, b, kind="3d"):
    """(N,) IoU of box i of ``a`` with box i of ``b`` (both (N, 7)); ``kind`` is 'bev' or
    '3d'."""
    _check_kind(kind)
    return _overlap(*_paired(a, b), kind)


def bev_iou(a, b):
    """(N, M) BEV IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7)."""
    return iou(a, b, "bev")


def iou_3d(a, b):
    """(N, M) 3D IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7)."""
    return iou(a, b, "3d")
