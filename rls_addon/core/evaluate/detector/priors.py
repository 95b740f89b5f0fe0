"""What the roadside detector knows of each class: its size prior (what a partial view is
grown to) and the largest object of the class, and the class of a box by its size.

The built-in priors are typical sizes (a 4.5 x 1.8 m car, a 1.8 x 0.7 m cyclist, a 0.7 m
pedestrian). A scene's own road users may differ (SUMO's person is 0.21 x 0.48 m: a
0.42 m square around it caps the BEV IoU near 0.45), so pedestrians and cyclists take
the scene's own sizes when they are known (``with_sizes``): the size of the commonest
type of each class among the scene's objects (``class_sizes``), as a learned detector's
anchors are the mean sizes of its training set's classes. The vehicle prior stays the
car's: vehicles span cars to buses, and the prior is what a car seen in part is grown
to."""

from dataclasses import dataclass, replace

import numpy as np

from ...labels import NAME_TO_ID

VEHICLE, PEDESTRIAN, CYCLIST = (NAME_TO_ID[n] for n in ("vehicle", "pedestrian", "cyclist"))
SCENE_SIZED = (PEDESTRIAN, CYCLIST)  # the classes whose prior a scene's sizes replace


@dataclass(frozen=True)
class ClassPrior:
    """A class's typical size (length, width, height in m) that partial views are grown
    to, and the largest length and width one object of the class can have."""
    label: int
    size: tuple
    max_length: float
    max_width: float


PRIORS = {
    VEHICLE: ClassPrior(VEHICLE, (4.5, 1.8, 1.6), 18.0, 3.2),
    CYCLIST: ClassPrior(CYCLIST, (1.8, 0.7, 1.7), 2.4, 1.1),
    PEDESTRIAN: ClassPrior(PEDESTRIAN, (0.7, 0.7, 1.75), 1.3, 1.3),
}


def with_sizes(sizes, priors=None):
    """``priors`` (default ``PRIORS``) with the pedestrian and cyclist sizes of
    ``sizes`` ({label id: (length, width, height) m}; None or missing classes keep the
    built-in ones). A class's largest object grows with its size (1.25 times its longer
    side at least)."""
    out = dict(PRIORS if priors is None else priors)
    for label, size in (sizes or {}).items():
        label = int(label)
        if label not in SCENE_SIZED or size is None:
            continue
        size = tuple(float(v) for v in size)
        if len(size) != 3 or not all(np.isfinite(size)) or min(size) <= 0:
            continue
        p = out[label]
        longest = max(size[:2])
        out[label] = replace(p, size=size, max_length=max(p.max_length, 1.25 * longest),
                             max_width=max(p.max_width, 1.25 * min(size[:2])))
    return out


def class_sizes(labels, instances, sizes):
    """{label id: (length, width, height)} of the commonest size among the objects of
    each class: ``labels`` (N,), ``instances`` (N,) the objects' ids (an object seen in
    many frames counts once) and ``sizes`` (N, 3) their boxes' sizes in m, rounded to 1 cm
    (the objects of one type have one size). Ties go to the smaller size."""
    labels = np.asarray(labels, np.int64).reshape(-1)
    instances = np.asarray(instances, np.int64).reshape(-1)
    sizes = np.round(np.asarray(sizes, np.float64).reshape(-1, 3), 2)
    out = {}
    for label in np.unique(labels):
        rows = np.flatnonzero(labels == label)
        _, first = np.unique(instances[rows], return_index=True)
        kinds, counts = np.unique(sizes[rows[first]], axis=0, return_counts=True)
        best = int(np.argmax(counts))  # the first of the most common: the smallest
        out[int(label)] = tuple(float(v) for v in kinds[best])
    return out


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
