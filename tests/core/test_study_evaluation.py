"""A placement study judged by detection (``study/evaluation.py``, ``rls study
--evaluate``): a parked truck in front of one candidate takes its AP down, as it takes
its visibility, while its InfraD (traffic removed) cannot see the truck at all."""

import math

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.errors import SceneError
from rls_addon.core.scene.instances import Instance
from rls_addon.core.study.config import StudyConfig
from rls_addon.core.study.detection import frame_truth
from rls_addon.core.study.loop import run_study

from .scenes import BOX_TRIS, box_vertices
from .test_study import TrafficStudyScene


def factory(name):
    return NumpyCaster, None


def study(truck):
    cfg = StudyConfig(device="generic_uniform32", k=(1, 2), disks=200, noise=False,
                      dropout=False, evaluate_frames=(1, 2, 3, 4))
    return run_study(TrafficStudyScene(truck=truck), cfg, factory=factory)


@pytest.fixture(scope="module")
def both():
    return study(True), study(False)


@pytest.mark.slow  # two whole studies with their traffic and detector
def test_an_occluded_candidates_ap_drops_as_its_visibility_does_and_its_infra_d_does_not(both):
    with_truck, clear = both
    names = [c.name for c in with_truck.candidates]
    a = names.index("pole A")
    ap = [ap for ap, _ in with_truck.evaluation.candidates]
    ap_clear = [ap for ap, _ in clear.evaluation.candidates]
    assert ap[a] < ap_clear[a] - 0.5          # the truck hides the cars from pole A
    assert ap[a] < min(ap[i] for i in range(len(ap)) if i != a)
    assert with_truck.visibility.candidates[a].score < clear.visibility.candidates[a].score
    assert with_truck.candidates[a].infra_d == clear.candidates[a].infra_d  # blind to it


@pytest.mark.slow  # two whole studies with their traffic and detector
def test_every_placement_is_scored_against_the_same_ground_truth(both):
    ev = both[0].evaluation
    gts = {rec["classes"]["vehicle"]["all"]["bev"]["0.5"]["gt"]
           for _, rec in ev.candidates + list(ev.sets.values())}
    assert len(gts) == 1 and gts.pop() > 0
    assert ev.frames == [1, 2, 3, 4] and ev.min_points == 5


@pytest.mark.slow  # two whole studies with their traffic and detector
def test_sets_are_scored_fused_and_the_best_by_ap_is_reported(both):
    ev = both[0].evaluation
    assert ev.sets and all(len(m) == 2 for m in ev.sets)
    best2 = ev.best[2]
    assert ev.ap_of(best2) == max(a for a, _ in ev.sets.values())
    assert ev.ap_of(ev.best[1]) == max(a for a, _ in ev.candidates)
    # the correlations ran over every placement scored, with their metrics
    assert len(ev.placements) == len(ev.candidates) + len(ev.sets)
    for metric in ("infra_d", "infra_nuc", "share_5", "share_20", "share_50"):
        assert ev.correlation[metric]["n"] == len(ev.placements)


@pytest.mark.slow  # two whole studies with their traffic and detector
def test_the_report_carries_the_evaluation(both):
    names = [c.name for c in both[0].candidates]
    d = both[0].evaluation.to_dict(names)
    assert set(d["best_by_ap"]) == {"1", "2"}
    assert d["candidates"][0]["candidate"] == names[0]
    assert "matches" not in d["candidates"][0]["result"]


def test_frame_truth_boxes_follow_the_objects_own_axes_and_scale():
    m = np.eye(4)
    yaw = math.radians(30)
    m[:3, :3] = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                          [0, 0, 1]]) @ np.diag([2.0, 1.0, 1.5])
    m[:3, 3] = (10.0, -4.0, 0.0)
    car = Instance("car", "car", "", 11, box_vertices((-1, -0.9, 0), (1, 0.9, 1)), BOX_TRIS,
                   np.ones(12), m, np.array([1]))
    pole = Instance("pole", "pole", "", 6, box_vertices((0, 0, 0), (1, 1, 5)), BOX_TRIS,
                    np.ones(12), np.eye(4), np.array([1]))

    class Obj:
        def __init__(self, i):
            self.instance = i
    t = frame_truth(7, [car, pole], [Obj(41), Obj(42)])
    assert len(t.boxes) == 1 and list(t.instance) == [41] and t.boxes.frame[0] == 7
    np.testing.assert_allclose(t.boxes.box[0], [10.0, -4.0, 0.75, 4.0, 1.8, 1.5, yaw],
                               atol=1e-12)


def test_evaluation_frames_must_be_traffic_frames():
    with pytest.raises(SceneError, match="not among the traffic frames"):
        StudyConfig(traffic_frames=(1, 2), evaluate_frames=(2, 3))
    assert StudyConfig(evaluate_frames=(3, 4)).traffic_frames == (3, 4)


class QueueScene(TrafficStudyScene):
    """The traffic scene without its truck, and a queue of two cars standing at a red
    light through every frame between pole A and the cars crossing the region."""

    def __init__(self, queue=True):
        super().__init__(truck=False)
        self.queue = queue

    def traffic(self, frames, labels):
        from rls_addon.core.scene.source import SceneRead

        out = super().traffic(frames, labels)
        if not self.queue:
            return out
        return {f: SceneRead(read.instances + [
            self._object(f"queued {i}", (-2.25, -0.9, 0.0), (2.25, 0.9, 1.5), 11,
                         (-6.0 + 5.5 * i, -6.5, 0.0)) for i in range(2)], read.materials)
                for f, read in out.items()}


def queue_study(queue, background="empty"):
    cfg = StudyConfig(device="generic_uniform32", k=(1,), disks=200, noise=False,
                      dropout=False, evaluate_frames=(1, 2, 3, 4),
                      evaluate_background=background, background_sweeps=2)
    return run_study(QueueScene(queue), cfg, factory=factory)


def found(record):
    """(frame, instance) of every vehicle found at BEV IoU 0.5."""
    return {(m["frame"], m["best"]["bev"]["instance"]) for m in record["matches"]
            if m["class"] == "vehicle" and m["status"]["bev"]["0.5"] == "tp"}


def found_instances(record):
    return {i for _, i in found(record)}


@pytest.mark.slow  # three small studies with their traffic and detector
def test_a_standing_queue_in_front_of_a_candidate_is_seen_and_lowers_its_ap():
    """The default background (the scene swept with every road user hidden) holds no
    car, so pole A finds the queue standing in front of it through every frame and loses
    the cars it hides: its AP drops because it sees the queue. Learned from the frames
    (a deployed unit over a short clip), the queue is background and vanishes: nobody
    finds it."""
    from rls_addon.core.scene.instances import instance_id

    queued = {instance_id(f"queued {i}") for i in range(2)}
    with_queue, clear = queue_study(True), queue_study(False)
    names = [c.name for c in with_queue.candidates]
    a = names.index("pole A")
    ap, rec = with_queue.evaluation.candidates[a]
    ap_clear, rec_clear = clear.evaluation.candidates[a]
    assert queued <= found_instances(rec)  # pole A sees the standing cars
    moving = {(f, i) for f, i in found(rec) if i not in queued}
    assert moving < found(rec_clear)  # and loses crossing cars they hide
    assert ap < ap_clear
    assert with_queue.evaluation.background["kind"] == "empty"
    learned = queue_study(True, "frames")
    assert not queued & set().union(*(found_instances(r) for _, r in
                                      learned.evaluation.candidates))
    assert learned.evaluation.background["kind"] == "frames"


@pytest.mark.slow  # two whole studies with their traffic and detector
def test_correlations_within_each_k_and_a_notice_on_few_vehicle_frames(both):
    """Sets of two have more points and more AP: pooled over k a correlation mixes "more
    sensors" with "better placement". Each k gets its own; with fewer than 200 counted
    vehicle-frames a notice names how many."""
    res = both[0]
    ev = res.evaluation
    assert set(ev.by_k) == {1, 2}
    ones = [r for r in ev.placements if len(r["members"]) == 1]
    assert ev.by_k[1]["infra_d"]["n"] == len(ones) == len(ev.candidates)
    assert ev.by_k[2]["infra_d"]["n"] == len(ev.placements) - len(ones)
    assert 0 < ev.vehicle_frames < 200
    assert ev.notices == [f"the evaluated frames hold {ev.vehicle_frames} counted "
                          "vehicle-frames (fewer than 200): each AP rests on few vehicles "
                          "and the correlations on noisy APs; evaluate more frames or "
                          "busier traffic"]
    assert ev.notices[0] in res.notices  # said on stderr too
    d = ev.to_dict([c.name for c in res.candidates])
    assert set(d["correlation_by_k"]) == {"1", "2"} and d["vehicle_frames"] == ev.vehicle_frames


def test_ap_chart_colours_placements_by_k_names_them_and_keeps_ap_on_0_1():
    from rls_addon.core.evaluate.correlation import correlation
    from rls_addon.core.study.ap_charts import ap_chart_figure

    rows = [dict(members=[i], sensors=[f"pole {i} pitch 15 yaw +0"], ap=0.2 + 0.1 * i,
                 infra_d=5.0 + i) for i in range(4)]
    rows += [dict(members=[0, i], sensors=["pole 0 pitch 15 yaw +0", f"pole {i} pitch 0 yaw +0"],
                  ap=0.6 + 0.05 * i, infra_d=12.0 + i) for i in range(1, 4)]
    by_k = {1: correlation([r["infra_d"] for r in rows[:4]], [r["ap"] for r in rows[:4]]),
            2: correlation([r["infra_d"] for r in rows[4:]], [r["ap"] for r in rows[4:]])}
    pooled = correlation([r["infra_d"] for r in rows], [r["ap"] for r in rows])
    fig = ap_chart_figure(rows, "infra_d", pooled, by_k, "cross3.blend")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "InfraD (points/m²)" and ax.get_ylim() == (-0.02, 1.02)
    assert ax.get_title().startswith("cross3.blend: vehicle AP against InfraD (points/m²)")
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0].startswith("k = 1 (4 placements): r = +1.00")
    assert legend[1].startswith("k = 2 (3 placements): r = +1.00")
    assert legend[2].startswith("all 7 placements: r = ")
    names = sorted(t.get_text() for t in ax.texts)
    assert len(names) == 7 and "pole 0 p15 + pole 3 p0" in names  # none crowd here
    colours = {tuple(c.get_facecolor()[0]) for c in ax.collections}
    assert len(colours) == 2
