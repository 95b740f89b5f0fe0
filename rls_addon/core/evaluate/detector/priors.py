"""What the roadside detector knows of each class: the sizes of its types (what a partial
view is grown to), the largest object of the class, and the class of a box by its size.

The built-in priors are typical sizes (a 4.5 x 1.8 m car, a 1.8 x 0.7 m cyclist, a
0.42 m pedestrian). A scene's own road users may differ: SUMO's person is 0.21 x 0.48 m
(a 0.42 m square around it caps the BEV IoU near 0.45), its motorcycle (a vehicle) is
2.2 x 0.9 m, longer than the built-in cyclist's bound. So when the scene's types are
known (``scene_types``: the distinct sizes of each class's objects, commonest first, as
SUMO's vTypes give them; a learned detector's anchors are its training set's sizes in
the same way), ``with_types`` takes them: each class's prior is its commonest type, a
partial view is grown to the smallest of its class's types that holds it
(``target_size``), and the pedestrian and cyclist bounds shrink to their largest type
plus ``SIZE_MARGIN`` (never beyond the built-in ones), so a motorcycle is a vehicle."""

from dataclasses import dataclass

import numpy as np

from ...labels import NAME_TO_ID

VEHICLE, PEDESTRIAN, CYCLIST = (NAME_TO_ID[n] for n in ("vehicle", "pedestrian", "cyclist"))
SIZE_MARGIN = 0.3  # m: how much larger than its type a view of an object may measure


@dataclass(frozen=True)
class ClassPrior:
    """A class's typical size (length, width, height in m) that partial views are grown
    to, the largest length and width one object of the class can have, and the sizes of
    all its types (``types``, the typical one first; empty: the typical one only)."""
    label: int
    size: tuple
    max_length: float
    max_width: float
    types: tuple = ()

    @property
    def sizes(self):
        return self.types or (self.size,)


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
        sizes = [tuple(float(v) for v in r[:3]) for r in rows]
        sizes = [s for s in sizes if len(s) == 3 and all(np.isfinite(s)) and min(s) > 0]
        if not sizes:
            continue
        p = out[label]
        long_side = max(max(s[:2]) for s in sizes)
        short_side = max(min(s[:2]) for s in sizes)
        max_length, max_width = p.max_length, p.max_width
        if label != VEHICLE:  # vehicles keep their bound: trailers, long buses, merges
            max_length = min(max_length, long_side + margin)
            max_width = min(max_width, short_side + margin)
        out[label] = ClassPrior(label, sizes[0], max_length, max_width, tuple(sizes))
    return out


def target_size(prior, length, width, margin=SIZE_MARGIN):
    """(length, width, height) a view ``length`` x ``width`` (length >= width) of the
    class is grown to: the smallest of its types by footprint that holds it (each side
    at least the view's less ``margin``), else its largest."""
    sizes = sorted(prior.sizes, key=lambda s: (s[0] * s[1], s))
    for s in sizes:
        if max(s[:2]) >= length - margin and min(s[:2]) >= width - margin:
            return s
    return sizes[-1]


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
