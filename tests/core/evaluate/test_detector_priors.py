"""The roadside detector's size knowledge (``detector/priors.py``): the scene's types of
road users, the class bounds they give, and the type a view is grown to."""

import numpy as np
import pytest

from rls_addon.core.evaluate.detector.priors import (CYCLIST, PEDESTRIAN, PRIORS, VEHICLE,
                                                     classify, scene_types, target_size,
                                                     with_types)

# SUMO's types as rls traffic generate writes them (core/traffic/sumo_run.py)
CAR, MOTO, VAN, BUS = (4.6, 1.8, 1.5), (2.2, 0.9, 1.5), (6.5, 2.16, 2.86), (12.0, 2.5, 3.4)
PERSON, BIKE = (0.21, 0.48, 1.72), (1.6, 0.65, 1.7)


def sumo_types():
    rows = [(VEHICLE, CAR)] * 14 + [(VEHICLE, MOTO)] * 2 + [(VEHICLE, VAN)] * 2 + \
           [(VEHICLE, BUS)] + [(PEDESTRIAN, PERSON)] * 5 + [(CYCLIST, BIKE)] * 2
    labels = [r[0] for r in rows]
    sizes = [r[1] for r in rows]
    # each object seen in two frames: it counts once
    return scene_types(labels + labels, list(range(len(rows))) * 2, sizes + sizes)


def test_scene_types_are_the_distinct_sizes_commonest_first():
    types = sumo_types()
    assert types[VEHICLE] == ((*CAR, 14), (*MOTO, 2), (*VAN, 2), (*BUS, 1))
    assert types[PEDESTRIAN] == ((*PERSON, 5),) and types[CYCLIST] == ((*BIKE, 2),)


def test_the_scenes_types_set_the_bounds_between_classes():
    priors = with_types(sumo_types())
    assert priors[VEHICLE].size == CAR and priors[PEDESTRIAN].size == PERSON
    # the largest cyclist type plus 0.3 m: SUMO's 2.2 m motorcycle is a vehicle; a
    # pedestrian's bound is its 0.48 m shoulders plus 0.3 m
    assert priors[CYCLIST].max_length == pytest.approx(1.9)
    assert priors[PEDESTRIAN].max_length == pytest.approx(0.78)
    assert priors[VEHICLE].max_length == PRIORS[VEHICLE].max_length  # buses, merges
    L, W, H = np.array([[2.15, 0.88, 1.45], [1.55, 0.6, 1.6], [0.45, 0.2, 1.7]]).T
    assert list(classify(L, W, H, priors)) == [VEHICLE, CYCLIST, PEDESTRIAN]
    assert list(classify(L, W, H)) == [CYCLIST, CYCLIST, PEDESTRIAN]  # built-in bounds


@pytest.mark.parametrize("view, want", [
    ((2.15, 0.88, 1.45), MOTO),        # a whole motorcycle is one
    ((2.0, 0.9, 0.76), CAR),           # the low part of a far car is a car, not a motorcycle
    ((3.0, 1.7, 1.45), CAR),           # a car seen in part
    ((4.0, 2.0, 2.8), VAN),            # a van in part: too tall for a car
    ((5.0, 2.2, 1.5), (5.0, 2.2, 1.5)),  # a car that caught something: kept, no truck
    ((11.9, 2.4, 3.3), BUS),           # a whole bus
    ((13.0, 2.6, 3.3), (13.0, 2.6, 3.3)),  # larger than any type: as it is
])
def test_a_view_is_grown_to_the_type_it_most_likely_shows(view, want):
    priors = with_types(sumo_types())
    assert target_size(priors[VEHICLE], *view) == pytest.approx(want)


def test_without_scene_types_every_view_grows_to_the_built_in_prior():
    for view in ((2.0, 0.9, 0.8), (3.0, 1.7, 1.4)):
        assert target_size(PRIORS[VEHICLE], *view) == PRIORS[VEHICLE].size
    assert target_size(PRIORS[VEHICLE], 5.0, 2.2, 1.5) == (5.0, 2.2, 1.6)  # larger: kept
