"""The study as the Study panel runs it, without Blender: the settings as typed
(``study_config``), the run in steps (``StudyRun``) against ``run_study``, and the
answer the panel shows (``core/study/answer.py``: scores, table, order, colours)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.errors import RegionError, SceneError
from rls_addon.core.study import answer
from rls_addon.core.study.config import StudyConfig, study_config
from rls_addon.core.study.loop import StudyRun, run_study

from .test_study import FakeStudyScene


def numpy_factory(name):
    return NumpyCaster, None


CFG = dict(device="generic_uniform32", k=(1, 2), pitches=(0.0, 20.0), disks=300,
           noise=False, dropout=False)


@pytest.fixture(scope="module")
def result():
    return run_study(FakeStudyScene(), StudyConfig(**CFG), factory=numpy_factory)


def test_settings_as_typed_make_the_command_lines_config():
    cfg = study_config(device="generic_uniform32", k="2,1,2", pitches="0:20:10", yaws="5",
                       grid_heights="5,8", traffic_frames="1-9:4", evaluate_frames="5",
                       visibility_labels="vehicle,cyclist", mounts=["pole A"])
    assert cfg == StudyConfig(device="generic_uniform32", k=(1, 2), pitches=(0.0, 10.0, 20.0),
                              yaws=(5.0,), grid_heights=(5.0, 8.0), traffic_frames=(1, 5, 9),
                              evaluate_frames=(5,), visibility_labels=("vehicle", "cyclist"),
                              mounts=("pole A",))
    empty = study_config(traffic_frames="  ", evaluate_frames=None)
    assert empty.traffic_frames == () and empty.evaluate_frames == ()
    # each error names the setting the way its user knows it
    with pytest.raises(RegionError, match=r"^--pitch: expected V, V1,V2"):
        study_config(pitches="ten")
    with pytest.raises(RegionError, match=r"^Pitches: expected V"):
        study_config(names={"pitches": "Pitches"}, pitches="ten")
    with pytest.raises(SceneError, match=r"^Sensors \(k\): sensor counts must be positive"):
        study_config(names={"k": "Sensors (k)"}, k="1.5")
    with pytest.raises(SceneError, match=r"^Traffic Frames: expected N, A-B"):
        study_config(names={"traffic_frames": "Traffic Frames"}, traffic_frames="x")


def test_a_study_in_steps_gives_run_studys_numbers(result):
    scene = FakeStudyScene()
    seen = []
    run = StudyRun(scene, StudyConfig(**CFG), lambda d, t, c, eta: seen.append(d),
                   numpy_factory)
    assert (run.done, run.total, run.scanned_all) == (0, 6, False)
    with pytest.raises(SceneError, match="6 of 6 candidates were not scanned"):
        run.finish()
    names = [run.step().name for _ in range(6)]
    assert run.scanned_all and seen == [1, 2, 3, 4, 5, 6]
    assert names == [c.name for c in result.candidates]
    stepped = run.finish()
    for k in (1, 2):
        a, b = stepped.searches[k], result.searches[k]
        assert [p.members for p in a.evaluated] == [p.members for p in b.evaluated]
        assert [(p.infra_d, p.infra_nuc) for p in a.evaluated] == \
            [(p.infra_d, p.infra_nuc) for p in b.evaluated]
        assert a.best.members == b.best.members
    assert stepped.title == "fake junction"  # a scene without a file: its name


def test_table_holds_every_candidate_and_each_larger_ks_front_and_best(result):
    rows = answer.table_rows(result)
    ones = [r for r in rows if r.k == 1]
    assert sorted(r.members for r in ones) == [(i,) for i in range(6)]
    twos = [r for r in rows if r.k == 2]
    s = result.searches[2]
    front = {p.members for p in s.front} | {s.best.members}
    assert {r.members for r in twos} == front and len(twos) < len(s.evaluated)
    best = next(r for r in twos if r.best)
    assert best.members == s.best.members
    assert best.infra_d == pytest.approx(s.best.infra_d, rel=1e-6)
    assert best.sensors == " + ".join(result.candidates[i].name for i in s.best.members)
    assert all(math.isnan(r.visibility) and math.isnan(r.ap) for r in rows)  # not asked for


def test_candidate_scores_and_their_colours(result):
    scores = answer.candidate_scores(result)
    assert set(scores) == {"infra_d", "infra_nuc"} == set(answer.available_scores(result))
    d = scores["infra_d"]
    assert d.tolist() == pytest.approx([c.infra_d for c in result.candidates], rel=1e-6)
    rgba = answer.score_colours(d, "infra_d")
    best, worst = int(np.nanargmax(d)), int(np.nanargmin(d))
    assert rgba[best][:3] == pytest.approx(np.array([253, 231, 37]) / 255)  # viridis top
    assert rgba[worst][:3] == pytest.approx(np.array([68, 1, 84]) / 255)    # bottom
    # lower is better for InfraNUC: its lowest value is the yellow one
    nuc = rgba_nuc = answer.score_colours([0.5, 1.5, float("nan")], "infra_nuc")
    assert nuc[0][:3] == pytest.approx(np.array([253, 231, 37]) / 255)
    assert rgba_nuc[2] == pytest.approx(answer.NO_VALUE_RGBA)
    assert answer.score_range_text([0.5, 1.5], "infra_nuc") == \
        "InfraNUC 1.5 (dark) to 0.5 (yellow)"
    assert answer.score_range_text([float("nan")], "ap") == "AP: no values"
    with pytest.raises(Exception, match="unknown study score 'colour'"):
        answer.score_colours(d, "colour")


def test_score_bands_follow_the_colours():
    # worst in band 1, best in band 16, no value in band 0; lower is better for InfraNUC
    assert answer.score_bands([0.0, 1.0, 0.5, float("nan")], "infra_d").tolist() == \
        [1, 16, 9, 0]
    assert answer.score_bands([0.5, 1.5], "infra_nuc").tolist() == [16, 1]
    assert answer.score_bands([3.0, 3.0], "ap").tolist() == [16, 16]  # colours: all yellow
    assert answer.score_bands([float("nan")], "ap").tolist() == [0]
    # each band's colour is the markers' viridis at its middle, and no value grey
    colours = answer.band_colours()
    assert colours.shape == (17, 4)
    assert colours[0] == pytest.approx(answer.NO_VALUE_RGBA)
    v = np.linspace(0.0, 1.0, 41)
    for value, band, rgba in zip(v, answer.score_bands(v, "infra_d"),
                                 answer.score_colours(v, "infra_d")):
        assert np.abs(colours[band][:3] - rgba[:3]).max() <= 0.12  # within its band


def test_table_order_puts_the_best_first_and_missing_values_last():
    nan = float("nan")
    rows = [SimpleNamespace(k=1, sensors="b", infra_d=5.0, infra_nuc=0.9, visibility=nan, ap=0.2),
            SimpleNamespace(k=2, sensors="a", infra_d=9.0, infra_nuc=0.4, visibility=0.8, ap=nan),
            SimpleNamespace(k=1, sensors="c", infra_d=7.0, infra_nuc=nan, visibility=0.9, ap=0.6)]
    assert answer.table_order(rows, "infra_d") == [1, 2, 0]
    assert answer.table_order(rows, "infra_nuc") == [1, 0, 2]
    assert answer.table_order(rows, "visibility") == [2, 1, 0]
    assert answer.table_order(rows, "ap") == [2, 0, 1]
    assert answer.table_order(rows, "k") == [2, 0, 1]  # then densest first
    assert answer.table_order(rows, "sensors") == [1, 0, 2]
    with pytest.raises(KeyError):
        answer.table_order(rows, "colour")
