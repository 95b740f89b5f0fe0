"""What the roadside detector knows of each class: the sizes of its types (what a partial
view is grown to), the largest object of the class, and the class of a box by its size.

The built-in priors are typical sizes (a 4.5 x 1.8 m car, a 1.8 x 0.7 m cyclist, a
0.42 m pedestrian). A scene's own road users may differ: SUMO's person is 0.21 x 0.48 m
(a 0.42 m square around it caps the BEV IoU near 0.45), its motorcycle (a vehicle) is
2.2 x 0.9 m, longer than the built-in cyclist's bound. So when the scene's types are
known (``scene_types``: the distinct sizes of each class's objects, commonest first, as
SUMO's vTypes give them; a learned detector's anchors are its training set's sizes in
the same way), ``with_types`` takes them: each class's prior is its commonest type, a
box is grown to the type it most likely shows (``target_size``), and the pedestrian and
cyclist bounds shrink to their largest type plus ``SIZE_MARGIN`` (never beyond the
built-in ones), so a motorcycle is a vehicle."""

from dataclasses import dataclass

import numpy as np

from ...labels import NAME_TO_ID

VEHICLE, PEDESTRIAN, CYCLIST = (NAME_TO_ID[n] for n in ("vehicle", "pedestrian", "cyclist"))
SIZE_MARGIN = 0.3  # m: how much larger than its type a view of an object may measure


@dataclass(frozen=True)
class ClassPrior:
    """A class's typical size (length, width, height in m) that partial views are grown
    to, the largest length and width one object of the class can have, and all its types
    (``types``: (length, width, height, objects), the typical one first; empty: the
    typical one only)."""
    label: int
    size: tuple
    max_length: float
    max_width: float
    types: tuple = ()

    @property
    def kinds(self):
        """((length, width, height, objects), ...) of the class's types."""
        return self.types or ((*self.size, 1),)


PRIORS = {
    VEHICLE: ClassPrior(VEHICLE, (4.5, 1.8, 1.6), 18.0, 3.2),
    CYCLIST: ClassPrior(CYCLIST, (1.8, 0.7, 1.7), 2.4, 1.1),
    PEDESTRIAN: ClassPrior(PEDESTRIAN, (0.42, 0.42, 1.75), 1.3, 1.3),
}


def scene_types(labels, instances, sizes):
    """{label id: ((length, width, height, objects), ...)}: the distinct sizes (to 1 cm)
    of each class's objects, the commonest first (ties: the smaller first). ``labels``
    (N,), ``instances`` (N,) the objects' ids (an object given in many frames counts
    once), ``sizes`` (N, 3) their boxes' sizes in m."""
    labels = np.asarray(labels, np.int64).reshape(-1)
    instances = np.asarray(instances, np.int64).reshape(-1)
    sizes = np.round(np.asarray(sizes, np.float64).reshape(-1, 3), 2)
    out = {}
    for label in np.unique(labels):
        rows = np.flatnonzero(labels == label)
        _, first = np.unique(instances[rows], return_index=True)
        kinds, counts = np.unique(sizes[rows[first]], axis=0, return_counts=True)
        order = np.argsort(-counts, kind="stable")  # unique's order: smaller first on ties
        out[int(label)] = tuple((*(float(v) for v in kinds[k]), int(counts[k]))
                                for k in order)
    return out


def with_types(types, priors=None, margin=SIZE_MARGIN):
    """``priors`` (default ``PRIORS``) with the scene's ``types`` (``scene_types``; a
    class it lacks keeps its built-in prior): the commonest type is the class's size,
    all its types are growth targets, and the pedestrian's and cyclist's largest length
    and width are their largest type's plus ``margin`` (at most the built-in bounds)."""
    out = dict(PRIORS if priors is None else priors)
    for label, rows in (types or {}).items():
        label = int(label)
        if label not in out:
            continue
        kinds = [(*(float(v) for v in r[:3]), int(r[3]) if len(r) > 3 else 1) for r in rows]
        kinds = [k for k in kinds if all(np.isfinite(k[:3])) and min(k[:3]) > 0]
        if not kinds:
            continue
        p = out[label]
        long_side = max(max(k[:2]) for k in kinds)
        short_side = max(min(k[:2]) for k in kinds)
        max_length, max_width = p.max_length, p.max_width
        if label != VEHICLE:  # vehicles keep their bound: trailers, long buses, merges
            max_length = min(max_length, long_side + margin)
            max_width = min(max_width, short_side + margin)
        out[label] = ClassPrior(label, kinds[0][:3], max_length, max_width, tuple(kinds))
    return out


def target_size(prior, length, width, height, margin=SIZE_MARGIN):
    """(length, width, height) a view ``length`` x ``width`` (length >= width),
    ``height`` tall, of the class is grown to (never shrunk: the box keeps the view where
    it is larger). A type holds the view when each of its sides is at least the view's
    less ``margin``; the view shows it whole when, beyond that, the view is no more than
    ``margin`` short of it in any side.

    - A view some type shows whole is that type (the smallest such): a full motorcycle.
    - A view about as large as the class's commonest type (its footprint at least the
      type's less the margin) is that type, or the view where larger: a car that caught
      a pedestrian's edge is no truck.
    - Otherwise the view is partial and is the commonest type that holds it (a car seen
      in part from afar is a car, not the motorcycle its visible part would fit), else
      the largest type."""
    kinds = sorted(prior.kinds, key=lambda k: (k[0] * k[1], k[:3]))
    view = (length, width, height)
    holding = [k for k in kinds if all(t >= v - margin for t, v in zip(_sides(k), view))]
    whole = shown_whole(prior, length, width, height, margin)
    if whole is not None:
        return whole
    common = max(kinds, key=lambda k: k[3])
    if all(v >= t - margin for t, v in zip(_sides(common)[:2], view[:2])):
        return tuple(max(t, v) for t, v in zip(_sides(common), view))
    if holding:
        return max(holding, key=lambda k: k[3])[:3]  # the first of the commonest
    return kinds[-1][:3]


def _sides(kind):
    """(long side, short side, height) of a type."""
    return max(kind[:2]), min(kind[:2]), kind[2]


def shown_whole(prior, length, width, height, margin=SIZE_MARGIN):
    """The smallest of the class's types a view shows whole (each of the type's sides
    within ``margin`` of the view's, either way), as (length, width, height), or None."""
    view = (length, width, height)
    for k in sorted(prior.kinds, key=lambda k: (k[0] * k[1], k[:3])):
        if all(abs(t - v) <= margin for t, v in zip(_sides(k), view)):
            return tuple(k[:3])
    return None


def classify(length, width, height, priors=PRIORS):
    """Class by size: a vehicle is longer than the largest cyclist or wider than it; a
    cyclist is longer than the largest pedestrian and narrow; a pedestrian is small on
    the ground; all at least 0.5 m tall above the ground and no larger than the largest
    vehicle. 0 is no object."""
    ped, cyc, veh = priors[PEDESTRIAN], priors[CYCLIST], priors[VEHICLE]
    label = np.zeros(len(length), np.int64)
    tall = height >= 0.5
    label[tall & (length <= ped.max_length) & (width <= cyc.max_width)] = PEDESTRIAN
    label[tall & (length > ped.max_length) & (length <= cyc.max_length)
          & (width <= cyc.max_width)] = CYCLIST
    big = tall & ((length > cyc.max_length) | (width > cyc.max_width))
    big &= (length <= veh.max_length) & (width <= veh.max_width)
    label[big] = VEHICLE
    return label
