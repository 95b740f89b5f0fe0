"""Issue 37's done-when on a junction built from scratch, as a user builds it
(``bench/junctions.py``'s cross3: netgenerate's signalised crossing with three lanes per
arm, ``rls scene from-net``, ``rls traffic generate`` at 3,600 vehicles an hour, ``rls
traffic import``, a Pandar64 on a corner pole 15 degrees down; then ``rls dataset`` ->
``rls detect`` -> ``rls evaluate`` with default settings). A short clip (the first 10 s
of the bench's window, 25 frames): queues stand at the red lights, and the detector
still finds the vehicles with 50+ points in the InfraLOB, standing and moving."""

from dataclasses import replace

import pytest

from ..sumo_nets import sumo_home

pytestmark = pytest.mark.slow  # a scene, its traffic and a dataset: about a minute


def test_standing_queues_are_found_at_a_signalised_junction(tmp_path):
    sumo_home()  # SUMO from the eclipse-sumo wheel, as the other SUMO tests ask for it
    from bench.junctions import JUNCTIONS, detection, figures, set_up

    spec = replace(JUNCTIONS["cross3"], end=160)
    blend = set_up(spec, tmp_path)
    result, timing = detection(spec, blend, tmp_path, "1-100:4")
    assert "Background: empty scene" in timing["detect_stdout"]
    got = figures(result)
    v = got["vehicle_0.5"]
    assert v["gt"] >= 150 and v["standing_share"] >= 0.4, v  # queues stand through the clip
    assert v["recall"] >= 0.9 and v["precision"] >= 0.9, v
    assert v["standing"]["recall"] >= 0.9 and v["moving"]["recall"] >= 0.85, v
    ped = got["pedestrian_0.3"]
    assert ped["gt"] >= 20 and ped["recall"] >= 0.8, ped
    assert got["pedestrian_0.5"]["recall"] is not None  # reported at KITTI's 0.5 too
