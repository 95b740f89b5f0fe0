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
    half = 0.5 * box[:, None, 3:5] * _CORNER_SIGNS  # (N, 4, 2) local offsets
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


def _z_overlap(za, ha, zb, hb):
    """Length shared by the vertical extents ``[z - h/2, z + h/2]`` (0 when apart),
    broadcast."""
    top = np.minimum(za + 0.5 * ha, zb + 0.5 * hb)
    bottom = np.maximum(za - 0.5 * ha, zb - 0.5 * hb)
    return np.maximum(top - bottom, 0.0)


def _may_meet(ax, ay, ar, bx, by, br):
    """Whether circumscribed circles (centres, radii; broadcast) meet: boxes whose
    circles do not cannot overlap. The margin keeps circles that just touch, where
    rounding could decide."""
    dx, dy, reach = ax - bx, ay - by, ar + br
    return dx * dx + dy * dy <= reach * reach * (1 + 1e-9)


def _measure(a, b, kind):
    """(P,) BEV intersection ('area'), BEV IoU ('bev') or 3D IoU ('3d') of row k of
    ``a`` with row k of ``b`` (both (P, 7))."""
    inter = _clip_area(a, b)
    if kind == "area":
        return inter
    if kind == "bev":
        return inter / (a[:, 3] * a[:, 4] + b[:, 3] * b[:, 4] - inter)
    volume = inter * _z_overlap(a[:, 2], a[:, 5], b[:, 2], b[:, 5])
    return volume / (a[:, 3] * a[:, 4] * a[:, 5] + b[:, 3] * b[:, 4] * b[:, 5] - volume)


def _overlap_at(a, b, i, j, kind):
    """(P,) ``_measure`` of the pairs ``a[i[k]]``, ``b[j[k]]``; only pairs that may meet
    are gathered and clipped, the others are 0."""
    out = np.zeros(len(i))
    near = _may_meet(a[i, 0], a[i, 1], _reach(a)[i], b[j, 0], b[j, 1], _reach(b)[j])
    if kind == "3d":
        near &= _z_overlap(a[i, 2], a[i, 5], b[j, 2], b[j, 5]) > 0
    idx = np.flatnonzero(near)
    if len(idx):
        out[idx] = _measure(a[i[idx]], b[j[idx]], kind)
    return out


def _all_pairs(a, b, kind):
    """(N, M) ``_measure`` of every box of ``a`` with every box of ``b``: only pairs that
    may meet are gathered and clipped."""
    out = np.zeros((len(a), len(b)))
    if not (len(a) and len(b)):
        return out
    near = _may_meet(a[:, None, 0], a[:, None, 1], _reach(a)[:, None],
                     b[None, :, 0], b[None, :, 1], _reach(b)[None, :])
    if kind == "3d":
        za, ha = a[:, None, 2], a[:, None, 5]
        near &= _z_overlap(za, ha, b[None, :, 2], b[None, :, 5]) > 0
    i, j = np.nonzero(near)
    out[i, j] = _measure(a[i], b[j], kind)
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
    """(N,) BEV intersection area (m^2) of box i of ``a`` with box i of ``b`` (both
    (N, 7))."""
    a, b = _paired(a, b)
    k = np.arange(len(a))
    return _overlap_at(a, b, k, k, "area")


def iou(a, b, kind="3d"):
    """(N, M) IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7); ``kind`` is
    'bev' or '3d'."""
    _check_kind(kind)
    return _all_pairs(_as_boxes(a, "a"), _as_boxes(b, "b"), kind)


def iou_paired(a, b, kind="3d"):
    """(N,) IoU of box i of ``a`` with box i of ``b`` (both (N, 7)); ``kind`` is 'bev' or
    '3d'."""
    _check_kind(kind)
    a, b = _paired(a, b)
    k = np.arange(len(a))
    return _overlap_at(a, b, k, k, kind)


def iou_at(a, b, i, j, kind="3d"):
    """(P,) IoU of the pairs ``a[i[k]]``, ``b[j[k]]`` (``a`` (N, 7), ``b`` (M, 7), ``i``
    and ``j`` (P,) indices): any chosen pairs at once, such as every pair within each
    frame, without the (N, M) table; ``kind`` is 'bev' or '3d'."""
    _check_kind(kind)
    a, b = _as_boxes(a, "a"), _as_boxes(b, "b")
    i = np.asarray(i, np.int64).reshape(-1)
    j = np.asarray(j, np.int64).reshape(-1)
    if len(i) != len(j):
        raise InputError(f"iou_at needs as many indices on each side, got {len(i)} and "
                         f"{len(j)}")
    return _overlap_at(a, b, i, j, kind)


def bev_iou(a, b):
    """(N, M) BEV IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7)."""
    return iou(a, b, "bev")


def iou_3d(a, b):
    """(N, M) 3D IoU of every box of ``a`` (N, 7) with every box of ``b`` (M, 7)."""
    return iou(a, b, "3d")
