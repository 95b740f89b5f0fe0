"""The paper's placement findings, reproduced on the sample scenes with a coarse device
(generic_uniform32: 32 beams from +10 to -30 degrees, 57,600 rays a frame).

A (T-junction): more LiDARs give a higher InfraD and a lower InfraNUC.
B (intersection): two LiDARs on the diagonal are more uniform than two on the same
  side at the same density -- except when the two sensors' innermost (densest) ground
  rings meet in the middle of the region, which is where the as-built traffic-light
  height puts them for this device. See docs/study.md, "What the sample scenes show".
C (four-lane road): too steep a downward pitch makes the cloud less uniform.
"""

import math

import pytest

from .conftest import bpy

from rls_addon.blender.scenes import build_scene
from rls_addon.blender.study import run_study
from rls_addon.core.study.config import StudyConfig

DEVICE = "generic_uniform32"
LOWEST_BEAM_DEG = 30.0
CORNERS = ("TL NE", "TL NW", "TL SE", "TL SW")


def by_members(result, k):
    names = [c.mount for c in result.candidates]
    return {frozenset(names[i] for i in p.members): p for p in result.searches[k].evaluated}


def test_a_more_lidars_raise_density_and_uniformity(scene):
    build_scene("t_junction", scene)
    res = run_study(scene, StudyConfig(device=DEVICE, k=(1, 2, 3),
                                       mounts=("TL NE", "TL NW", "TL SE", "TL SW", "SL S")))
    best = [res.searches[k].best for k in (1, 2, 3)]
    d = [b.infra_d for b in best]
    u = [b.infra_nuc for b in best]
    # measured: InfraD 10.7 -> 21.2 -> 31.8, InfraNUC 1.05 -> 0.68 -> 0.62
    assert d[0] < d[1] < d[2]
    assert u[0] > u[1] > u[2]
    # the same along one nested placement (the paper adds sensors one by one)
    seq = by_members(res, 1)[frozenset({"TL SW"})], by_members(res, 2)[frozenset({"TL SW", "TL NE"})], \
        by_members(res, 3)[frozenset({"TL SW", "TL NE", "TL NW"})]
    assert seq[0].infra_d < seq[1].infra_d < seq[2].infra_d
    assert seq[0].infra_nuc > seq[1].infra_nuc > seq[2].infra_nuc
    # every 3-set beats every single sensor on both counts
    worst3 = max(p.infra_nuc for p in res.searches[3].evaluated)
    assert worst3 < min(c.infra_nuc for c in res.candidates)


def _pairs_at_height(scene, lidar_height):
    """Diagonal and same-side pairs with the corner poles scaled so the LiDAR sits at
    about ``lidar_height`` m; returns (same-side pairs, diagonal pairs, actual height)."""
    for n in CORNERS:
        for obj in (bpy.data.objects[n], bpy.data.objects[n + " arm"]):
            obj.scale = (1.0, 1.0, (lidar_height - 0.25) / 6.15)
    bpy.context.view_layer.update()
    res = run_study(scene, StudyConfig(device=DEVICE, k=(2,), mounts=CORNERS))
    ev = by_members(res, 2)
    same = [ev[frozenset(p)] for p in (("TL NW", "TL NE"), ("TL SW", "TL SE"),
                                       ("TL NW", "TL SW"), ("TL NE", "TL SE"))]
    diag = [ev[frozenset(p)] for p in (("TL NE", "TL SW"), ("TL NW", "TL SE"))]
    return same, diag, res.candidates[0].position[2], res


@pytest.mark.parametrize("height", [4.35, 9.0])
def test_b_diagonal_pair_more_uniform_than_same_side(scene, height):
    build_scene("intersection", scene)
    same, diag, z, _ = _pairs_at_height(scene, height)
    assert z == pytest.approx(height, abs=0.01)
    d_same = sum(p.infra_d for p in same) / 4
    d_diag = sum(p.infra_d for p in diag) / 2
    assert d_diag == pytest.approx(d_same, rel=0.02)  # similar density
    # measured: 4.35 m: same 0.95, diagonal 0.81; 9 m: same 0.79, diagonal 0.65
    assert max(p.infra_nuc for p in diag) < 0.92 * min(p.infra_nuc for p in same)


def test_b_exception_when_the_inner_rings_meet_in_the_middle(scene):
    """At the as-built height (LiDAR 6.4 m on a 6 m traffic-light pole) the lowest beam
    reaches the ground 11.1 m out, and the diagonal sensors are 25.5 m apart: their
    densest rings cross the centre together, so the diagonal pair is the less uniform
    one. Recorded, not hidden: the finding depends on height, beam layout and spacing."""
    build_scene("intersection", scene)
    same, diag, z, res = _pairs_at_height(scene, 6.4)
    r_blind = z / math.tan(math.radians(LOWEST_BEAM_DEG))
    spacing = math.dist(res.candidates[0].position[:2], res.candidates[3].position[:2])
    assert 0.7 < 2 * r_blind / spacing < 1.05
    # measured: same side 0.66 on average, diagonal 0.85
    assert min(p.infra_nuc for p in diag) > max(p.infra_nuc for p in same)
    dm = res.density(next(iter(diag)).members)
    centre = dm.values[dm.values.shape[0] // 2 - 2: dm.values.shape[0] // 2 + 2,
                       dm.values.shape[1] // 2 - 2: dm.values.shape[1] // 2 + 2]
    assert centre.mean() > 1.5 * (diag[0].infra_d)  # the band of stacked rings


def test_c_too_steep_a_pitch_hurts_uniformity(scene):
    build_scene("four_lane", scene)
    pitches = (0.0, 10.0, 45.0, 60.0)
    res = run_study(scene, StudyConfig(device=DEVICE, k=(2,), mounts=("SL N +0", "SL S +0"),
                                       pitches=pitches))
    pair = {}
    for p in res.searches[2].evaluated:
        a, b = (res.candidates[i] for i in p.members)
        if a.pitch_deg == b.pitch_deg:
            pair[a.pitch_deg] = p
    # measured pairs (facing each other across the road): pitch 0: InfraD 16.3, NUC 0.63;
    # 10: 23.3, 0.61; 45: 37.8, 0.93; 60: 31.2, 1.02 (15: 0.79, 20: 0.89, 30: 0.90)
    assert pair[45.0].infra_nuc > pair[10.0].infra_nuc
    assert pair[60.0].infra_nuc > pair[45.0].infra_nuc > pair[0.0].infra_nuc
    single = {c.pitch_deg: c.infra_nuc for c in res.candidates if c.mount == "SL N +0"}
    assert single[60.0] > single[45.0] > single[10.0]
    # tilting down gains density at first: the cost of a steep pitch is uniformity
    assert pair[45.0].infra_d > pair[10.0].infra_d > pair[0.0].infra_d
