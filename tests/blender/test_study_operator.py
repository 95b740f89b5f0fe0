"""The placement study from the Study panel (``bpy.ops.rls.study``) on the sample
intersection with its mounts: the same numbers as ``rls study`` in a subprocess, the
answer in the scene (markers, the best sets as LiDARs, charts, the table), Esc with
nothing half-made, undo, and bad input with one error."""

import csv
import math
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from .conftest import bpy

ROOT = Path(__file__).resolve().parents[2]


def intersection(path):
    """The sample intersection (scene B, eight mounts), saved as ``path``."""
    from rls_addon.blender.scenes import build_scene

    build_scene("intersection", bpy.context.scene)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return bpy.context.scene


def study_objects():
    names = {c.name for c in bpy.data.collections if c.name.startswith("RLS Study")}
    images = {i.name for i in bpy.data.images if i.get("rls_study")}
    return names, images


def without_seconds(path):
    return [{k: v for k, v in r.items() if k != "scan_seconds"}
            for r in csv.DictReader(open(path))]


@pytest.mark.slow
def test_study_operator_equals_rls_study_and_leaves_its_answer(scene, tmp_path):
    pytest.importorskip("matplotlib")
    blend = tmp_path / "intersection.blend"
    sc = intersection(blend)
    p = sc.rls_study
    p.k, p.traffic, p.evaluate = "1,2", "20-30:10", "20-30:10"
    p.output_dir = str(tmp_path / "ui")
    bpy.ops.ed.undo_push(message="before the study")
    # as a click runs it: an undo step is pushed when it finishes
    assert bpy.ops.rls.study("EXEC_DEFAULT", True) == {"FINISHED"}

    cli = subprocess.run([sys.executable, "-m", "rls_addon", "study", str(blend), "--k", "1,2",
                          "--traffic", "20-30:10", "--evaluate", "20-30:10", "--out",
                          str(tmp_path / "cli")], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert cli.returncode == 0, cli.stderr
    # the same numbers, byte for byte (the scans' own seconds aside)
    ui, cl = tmp_path / "ui", tmp_path / "cli"
    assert (ui / "placements.csv").read_bytes() == (cl / "placements.csv").read_bytes()
    assert without_seconds(ui / "candidates.csv") == without_seconds(cl / "candidates.csv")
    candidates = without_seconds(cl / "candidates.csv")
    assert len(candidates) == 8  # the intersection's eight mounts

    # candidates as markers in "RLS Study", coloured by InfraD, with their scores
    from rls_addon.blender.study_answer import markers

    marks = markers(sc)
    assert [m["rls_candidate"] for m in marks] == list(range(8))
    assert all(m.users_collection[0].name == "RLS Study candidates" for m in marks)
    for m, row in zip(marks, candidates):
        assert m["rls_infra_d"] == pytest.approx(float(row["infra_d"]), abs=1e-6)
        assert m["rls_visibility"] == pytest.approx(float(row["share_20"]), abs=1e-6)
        assert m["rls_ap"] == pytest.approx(float(row["ap_vehicle_bev50"]), abs=1e-6)
        assert m.hide_render
    densest = max(range(8), key=lambda i: float(candidates[i]["infra_d"]))
    assert tuple(marks[densest].color)[:3] == pytest.approx((253 / 255, 231 / 255, 37 / 255))
    assert p.color_range.startswith("InfraD ")
    # Solid shading shows each marker's own material: its band's colour (dense yellow)
    import mathutils

    from rls_addon.core.study.answer import band_colours, score_bands

    bands = score_bands([m["rls_infra_d"] for m in marks], "infra_d")
    for m, band in zip(marks, bands):
        slot = m.material_slots[0]
        assert slot.link == "OBJECT" and slot.material.name == f"RLS Study marker {band:02d}"
        srgb = mathutils.Color(slot.material.diffuse_color[:3]).from_scene_linear_to_srgb()
        assert tuple(srgb) == pytest.approx(tuple(band_colours()[band][:3]), abs=1e-3)
    assert bands[densest] == 16 and min(bands) == 1
    p.color_by = "ap"  # recoloured at once
    assert p.color_range.startswith("AP ")

    # the best set of each k as LiDAR objects at the candidates' poses, ready to scan
    from rls_addon.blender.sensor import lidar_objects
    from rls_addon.operators.study import LAST_STUDY

    result = LAST_STUDY["result"]
    lidars = {o.name: o for o in lidar_objects(sc)}
    for k in (1, 2):
        best = result.searches[k].best.members
        for i in best:
            c = result.candidates[i]
            obj = lidars[f"k{k} {c.name}"]
            assert obj.users_collection[0].name == f"RLS Study best k={k}"
            assert np.array(obj.matrix_world) == pytest.approx(c.pose, abs=1e-5)
            assert obj.rls_lidar.preset_id == "generic_uniform32"
    got = LAST_STUDY["made"]["lidars"][1][0]
    bpy.context.view_layer.objects.active = got
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    assert len(bpy.data.objects[f"{got.name} points"].data.vertices) > 1000

    # the charts as images, the table as the front and best sets
    _, images = study_objects()
    assert {"RLS Study pareto.png", "RLS Study density_k1.png", "RLS Study density_k2.png",
            "RLS Study visibility.png", "RLS Study ap_vs_infra_d.png"} <= images
    assert p.chart.name == "RLS Study pareto.png" and p.chart.size[0] > 500
    places = list(csv.DictReader(open(cl / "placements.csv")))
    shown = [r for r in places if r["k"] == "1" or r["pareto"] == "1" or r["best"] == "1"]
    assert [(r.k, r.sensors) for r in p.rows] == [(int(r["k"]), r["sensors"]) for r in shown]
    for row, ref in zip(p.rows, shown):
        assert row.infra_d == pytest.approx(float(ref["infra_d"]), rel=1e-5)
        assert row.visibility == pytest.approx(float(ref["share_20"]), rel=1e-5)
        assert row.best == (ref["best"] == "1")
        assert math.isnan(row.ap) == (ref["ap_vehicle_bev50"] == "")

    # undo puts the scene back as it was before the study
    assert bpy.ops.ed.undo() == {"FINISHED"}
    sc = bpy.context.scene
    assert study_objects() == (set(), set())
    assert not sc.rls_study.has_result and len(sc.rls_study.rows) == 0
    assert not [o for o in sc.objects if o.name.startswith("k1 ")]


def _modal(scene, cfg, steps, tmp_path):
    """Run the modal loop (what a UI click runs) with synthetic events: ``steps`` timer
    events, then Esc."""
    from rls_addon.blender.study_job import StudyJob
    from rls_addon.operators.study import LAST_STUDY, RLS_OT_study as Op

    ctx = bpy.context
    reports = []
    fake = SimpleNamespace(_timer=None, report=lambda kind, msg: reports.append(msg))
    fake._end = lambda c: Op._end(fake, c)
    fake._status = lambda c, t: Op._status(fake, c, t)
    fake._report = lambda job: Op._report(fake, job)
    fake._job = StudyJob(scene, cfg, str(tmp_path / "report"))
    ctx.window_manager.progress_begin(0, 1000)
    assert Op.modal(fake, ctx, SimpleNamespace(type="MOUSEMOVE")) == {"PASS_THROUGH"}
    for _ in range(steps):
        assert Op.modal(fake, ctx, SimpleNamespace(type="TIMER")) == {"RUNNING_MODAL"}
    stage = fake._job.stage
    assert Op.modal(fake, ctx, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    assert LAST_STUDY == {"cancelled": True, "stage": stage}
    assert "Study stopped: nothing was added to the scene" in reports
    return fake._job


def test_esc_stops_the_study_with_nothing_half_made(scene, tmp_path):
    from rls_addon.blender.study_job import study_config

    sc = intersection(tmp_path / "intersection.blend")
    sc.frame_set(7)
    sc.rls_study.k, sc.rls_study.traffic = "1", "20"  # the study visits frame 20
    cfg = study_config(sc, sc.rls_study, "InfraLOB")
    before = {o.name for o in bpy.data.objects}
    # stopped while scanning (after reading the scene and two candidates), then after
    # everything but the answer: nothing of it is in the scene, no report is written
    for steps, stage in ((3, "scan"), (1 + 8 + 2, "answer")):
        job = _modal(sc, cfg, steps, tmp_path)
        assert job.stage == stage and job.cancelled and job.made is None
        assert study_objects() == (set(), set())
        assert {o.name for o in bpy.data.objects} == before
        assert not sc.rls_study.has_result and len(sc.rls_study.rows) == 0
        assert sc.frame_current == 7
        assert not (tmp_path / "report").exists()


def test_a_new_study_replaces_the_last_answer(scene, tmp_path):
    sc = intersection(tmp_path / "intersection.blend")
    p = sc.rls_study
    p.k = "1"
    assert bpy.ops.rls.study() == {"FINISHED"}
    mine = bpy.data.objects.new("my note", None)  # a user's object put in the collection
    bpy.data.collections["RLS Study"].objects.link(mine)
    for o in sc.objects:
        o.select_set(o.name in ("TL NE", "TL SW", "InfraLOB"))
    p.mounts_from, p.pitches = "SELECTED", "0,10"
    assert bpy.ops.rls.study() == {"FINISHED"}
    from rls_addon.blender.study_answer import markers

    assert [m.name for m in markers(sc)] == [f"Study: TL {c} pitch {a} yaw +0"
                                            for c in ("NE", "SW") for a in (0, 10)]
    assert len(p.rows) == 4
    best = [o.name for o in sc.objects if o.get("rls_study_k")]  # the last study's only
    assert len(best) == 1 and best[0].startswith("k1 TL ") and "pitch" in best[0]
    assert "my note" in sc.collection.objects  # kept, in the scene's own collection


@pytest.mark.parametrize("settings, message", [
    ({"k": "two"}, "Sensors (k): expected V, V1,V2"),
    ({"k": "9"}, "k = 9 needs 9 distinct mounts; the candidates have 8"),
    ({"pitches": "0:x:5"}, "Pitches: expected"),
    ({"traffic": "1-"}, "Traffic Frames: expected N, A-B"),
    ({"mounts_from": "SELECTED"}, "no mount selected"),
    ({"mounts_from": "NONE"}, "no candidates: choose mounts, or turn the grid on"),
    ({"device_id": "no_such_device"}, "no_such_device"),
])
def test_bad_settings_are_one_error_and_change_nothing(scene, tmp_path, settings, message):
    sc = intersection(tmp_path / "intersection.blend")
    for o in sc.objects:
        o.select_set(False)
    for name, value in settings.items():
        setattr(sc.rls_study, name, value)
    with pytest.raises(RuntimeError, match=re.escape(message)):
        bpy.ops.rls.study()
    assert study_objects() == (set(), set()) and not sc.rls_study.has_result


def test_an_existing_report_is_refused_before_any_scan(scene, tmp_path):
    sc = intersection(tmp_path / "intersection.blend")
    out = tmp_path / "report"
    out.mkdir()
    (out / "study.json").write_text("{}")
    sc.rls_study.output_dir = str(out)
    with pytest.raises(RuntimeError, match="study.json already exists: turn on Overwrite"):
        bpy.ops.rls.study()
    assert (out / "study.json").read_text() == "{}"
    sc.rls_study.k, sc.rls_study.overwrite = "1", True
    assert bpy.ops.rls.study() == {"FINISHED"}
    assert (out / "study.json").read_text() != "{}"


def test_study_panel_draws_settings_and_the_sortable_table(scene, tmp_path, monkeypatch):
    from rls_addon import ui
    from rls_addon.core.study import loop

    from .test_ui_panels import Recorder, _draw, _explode

    sc = intersection(tmp_path / "intersection.blend")
    sc.rls_study.k = "1,2"
    lob = bpy.data.objects["InfraLOB"]
    ctx = SimpleNamespace(object=lob, active_object=lob, scene=sc)
    before = _draw(ui.OBJECT_PT_rls_study, ctx)
    assert ("rls.study",) in [a for n, a, _ in before if n == "operator"]
    assert not any(n == "template_list" for n, _, _ in before)  # no answer yet
    assert bpy.ops.rls.study() == {"FINISHED"}
    monkeypatch.setattr(loop.StudyRun, "step", _explode)  # drawing runs no study
    monkeypatch.setattr(loop.StudyRun, "__init__", _explode)
    log = _draw(ui.OBJECT_PT_rls_study, ctx) + _draw(ui.OBJECT_PT_rls_study_options, ctx)
    props = {a[1] for n, a, _ in log if n == "prop"}
    assert {"device", "k", "pitches", "yaws", "mounts_from", "use_grid", "traffic",
            "evaluate", "output_dir", "color_by", "chart", "disks", "radius", "seed",
            "noise", "backend"} <= props
    (tl,) = [a for n, a, _ in log if n == "template_list"]
    assert tl[0] == "RLS_UL_study_rows" and tl[3] == "rows"
    # the list sorts by a score, best first, and draws a row per set
    rows = sc.rls_study.rows
    ul = SimpleNamespace(filter_name="", sort_by="infra_nuc", bitflag_filter_item=1 << 30)
    _, neworder = ui.RLS_UL_study_rows.filter_items(ul, None, sc.rls_study, "rows")
    shown = sorted(range(len(rows)), key=lambda i: neworder[i])
    nucs = [rows[i].infra_nuc for i in shown]
    assert nucs == sorted(nucs) and len(shown) == len(rows)
    item_log = []
    ui.RLS_UL_study_rows.draw_item(ul, None, Recorder(item_log), sc.rls_study, rows[0], 0,
                                   sc.rls_study, "row_index", 0)
    texts = [kw.get("text") for n, _, kw in item_log if n == "label"]
    assert rows[0].sensors in texts and f"{rows[0].infra_d:.2f}" in texts


def test_markers_stand_at_their_candidates_poses(scene):
    """Each marker is its candidate's sensor-to-world pose. A nested list given to
    ``matrix_world`` is read column by column: the markers had stood at the world's
    origin, turned the inverse way, whatever the candidates' poses."""
    from rls_addon.blender.study_answer import _markers
    from rls_addon.core.study.candidates import pose_matrix

    cands = [SimpleNamespace(index=i, name=f"c{i}", pose=pose_matrix(p, yaw, pitch, roll))
             for i, (p, yaw, pitch, roll) in enumerate([((25.0, 9.0, 8.4), 150.0, 15.0, 0.0),
                                                        ((-12.0, 3.0, 6.0), -40.0, 35.0, 5.0)])]
    coll = bpy.data.collections.new("RLS Study candidates")
    scene.collection.children.link(coll)
    marks = _markers(coll, SimpleNamespace(candidates=cands), {})
    bpy.context.view_layer.update()
    for m, c in zip(marks, cands):
        assert np.array(m.matrix_world) == pytest.approx(c.pose, abs=1e-5)
