"""``rls study`` as users run it, on scenes written by sample_scenes/make_scenes.py."""

import csv
import json
import subprocess
import sys

import pytest

from .conftest import ROOT, one_line_error, rls
from tests.core.external_tools import require_module


@pytest.fixture(scope="session")
def sample_blends(tmp_path_factory):
    out = tmp_path_factory.mktemp("scenes")
    proc = subprocess.run([sys.executable, str(ROOT / "sample_scenes" / "make_scenes.py"),
                           "--out", str(out), "t_junction", "four_lane"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return {p.stem: p for p in out.glob("*.blend")}


def summary_of(proc):
    return json.loads(proc.stdout)


def test_study_writes_tables_and_charts(sample_blends, tmp_path):
    out = tmp_path / "study"
    proc = rls("study", sample_blends["t_junction"], "--k", "1,2", "--mount", "TL NE",
               "--mount", "TL SW", "--mount", "TL NW", "--out", out)
    assert proc.returncode == 0, proc.stderr
    s = summary_of(proc)
    assert s["candidates"] == 3 and s["structure_builds"] == 1
    assert set(s["best"]) == {"1", "2"}
    assert "[3/3] TL NW" in proc.stderr and "s left" in proc.stderr
    rows = list(csv.DictReader(open(out / "candidates.csv")))
    assert [r["name"] for r in rows] == ["TL NE", "TL SW", "TL NW"]  # as given
    assert all(float(r["infra_d"]) > 0 and float(r["infra_nuc"]) > 0 for r in rows)
    places = list(csv.DictReader(open(out / "placements.csv")))
    assert len(places) == 3 + 3
    assert sum(int(r["best"]) for r in places) == 2
    report = json.loads((out / "study.json").read_text())
    front2 = report["placements"]["2"]["pareto_front"]
    assert front2 and all(len(p["sensors"]) == 2 for p in front2)
    hidden = report["hidden_traffic"]  # the scene's traffic: vehicles, pedestrians, cyclists
    assert {"Car east", "Car turning", "Car west", "Truck parked 3"} < set(hidden)
    assert {n.split()[0] for n in hidden} == {"Car", "Van", "Truck", "Pedestrian", "Cyclist"}
    assert report["placements"]["2"]["best_density"]["units"] == "points per square metre"
    require_module("matplotlib", "matplotlib==3.11.2")
    for name in ("pareto.png", "density_k1.png", "density_k2.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a second run refuses to replace the report, then replaces it with --overwrite
    again = rls("study", sample_blends["t_junction"], "--mount", "TL NE", "--out", out)
    assert "already exists" in one_line_error(again)
    assert rls("study", sample_blends["t_junction"], "--mount", "TL NE", "--out", out,
               "--overwrite").returncode == 0


def test_study_pitch_and_grid_candidates(sample_blends, tmp_path):
    proc = rls("study", sample_blends["four_lane"], "--mount", "SL N +0", "--mount", "SL S +0",
               "--pitch", "0:30:15", "--k", "2", "--out", tmp_path / "a")
    assert proc.returncode == 0, proc.stderr
    s = summary_of(proc)
    assert s["candidates"] == 6
    assert len(s["best"]["2"]["sensors"]) == 2
    assert {n.split(" pitch")[0] for n in s["best"]["2"]["sensors"]} == {"SL N +0", "SL S +0"}
    grid = rls("study", sample_blends["four_lane"], "--grid", "25", "--heights", "7",
               "--k", "2", "--out", tmp_path / "b")
    assert grid.returncode == 0, grid.stderr
    # x in -25, 0, 25 and y = -11 over the 50 m x 22 m region, at one height
    assert summary_of(grid)["candidates"] == 3


@pytest.mark.parametrize("args, message", [
    (["--k", "x"], "--k"),
    (["--lob", "Nope"], "no object named 'Nope'"),
    (["--mount", "Nope"], "no mount object named 'Nope'"),
    (["--mount", "TL NE", "--k", "2"], "distinct mounts"),
    (["--device", "no_such_device"], "no_such_device"),
    (["--device", "hesai_pandarqt", "--rotation-hz", "20"], "rotation_hz 20 Hz"),
    (["--device", "ouster_os1_64", "--lidar-mode", "4096x5"], "lidar mode '4096x5'"),
])
def test_study_errors_are_one_line(sample_blends, tmp_path, args, message):
    proc = rls("study", sample_blends["t_junction"], "--out", tmp_path / "o", *args)
    assert message in one_line_error(proc)
    assert not (tmp_path / "o").exists()  # issue 31: a failed study left an empty folder


def test_study_missing_scene(tmp_path):
    proc = rls("study", tmp_path / "missing.blend", "--out", tmp_path / "o")
    assert "scene file not found" in one_line_error(proc)


TRUCK = r"""
import sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
if not hasattr(bpy.types.Object, "rls_lidar"):
    rls_addon.register()
from rls_addon.blender.scenes.build import box, collection, mount_position, standard_materials
pole = bpy.data.objects["TL NE"]
x, y, _ = mount_position(pole)
# a 10 m x 3 m x 4.5 m truck parked on the kerb lane right in front of the pole
truck = box(collection(bpy.context.scene, "Vehicles"), "Parked truck",
            (x - 7.0, y - 4.0, 0.0), (x + 3.0, y - 1.0, 4.5), standard_materials()["paint"])
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
"""


def test_study_with_traffic_sees_a_parked_truck_the_traffic_free_metrics_miss(sample_blends,
                                                                              tmp_path):
    blend = tmp_path / "t_junction_truck.blend"
    proc = subprocess.run([sys.executable, "-c", TRUCK, str(ROOT), str(sample_blends["t_junction"]),
                           str(blend)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    def study(scene, out):
        proc = rls("study", scene, "--k", "1,2", "--mount", "TL NE", "--mount", "TL NW",
                   "--mount", "TL SE", "--mount", "TL SW", "--pitch", "10",
                   "--traffic", "20-40:5", "--out", out)
        assert proc.returncode == 0, proc.stderr
        return proc, {r["name"]: r for r in csv.DictReader(open(out / "candidates.csv"))}

    _, clear = study(sample_blends["t_junction"], tmp_path / "clear")
    out = tmp_path / "study"
    proc, rows = study(blend, out)
    ne = rows["TL NE"]
    # the truck is traffic: left out of InfraD, so the pole keeps its InfraD and rank ...
    report = json.loads((out / "study.json").read_text())
    assert "Parked truck" in report["hidden_traffic"]
    assert ne["infra_d"] == clear["TL NE"]["infra_d"]
    assert ne["rank_infra_d"] == clear["TL NE"]["rank_infra_d"] == "1"
    # ... but with the traffic in view it hides the cars from that pole: last by visibility
    # (measured: share_20 0.94 -> 0.72, rank 3 -> 4 of 4)
    assert int(ne["rank_visibility"]) > int(ne["rank_infra_d"])
    assert int(ne["rank_visibility"]) == len(rows) > int(clear["TL NE"]["rank_visibility"])
    assert float(ne["share_20"]) < float(clear["TL NE"]["share_20"])
    assert float(ne["share_20"]) < max(float(r["share_20"]) for r in rows.values())
    assert report["visibility"]["frames"] == [20, 25, 30, 35, 40]
    assert any(d["candidate"] == "TL NE" for d in report["visibility"]["rank_disagreements"])
    assert set(summary_of(proc)["best_by_visibility"]) == {"1", "2"}
    require_module("matplotlib", "matplotlib==3.11.2")
    assert (out / "visibility.png").read_bytes()[:4] == b"\x89PNG"


def test_study_evaluate_scores_placements_by_detection(sample_blends, tmp_path):
    """--evaluate: the detector's AP per candidate and per reported set in the tables and
    study.json, the best set by AP, and AP against each metric charted."""
    out = tmp_path / "study"
    proc = rls("study", sample_blends["t_junction"], "--k", "1,2", "--mount", "TL NE",
               "--mount", "TL NW", "--mount", "TL SW", "--pitch", "10",
               "--evaluate", "20-40:5", "--out", out)
    assert proc.returncode == 0, proc.stderr
    s = summary_of(proc)
    assert set(s["best_by_ap"]) == {"1", "2"}
    rows = list(csv.DictReader(open(out / "candidates.csv")))
    assert all(0.0 <= float(r["ap_vehicle_bev50"]) <= 1.0 for r in rows)
    assert all(r["share_20"] != "" for r in rows)  # the evaluate frames are traffic frames
    report = json.loads((out / "study.json").read_text())
    ev = report["evaluation"]
    assert ev["frames"] == [20, 25, 30, 35, 40] and ev["min_points"] == 5
    assert set(ev["correlation"]) >= {"infra_d", "infra_nuc", "share_20"}
    best = s["best_by_ap"]["1"]
    assert best["ap"] == pytest.approx(max(float(r["ap_vehicle_bev50"]) for r in rows),
                                      abs=1e-6)  # the table's 6 decimals
    for name in ("infra_d", "infra_nuc", "share_20"):
        assert (out / f"ap_vs_{name}.png").read_bytes()[:4] == b"\x89PNG"
    line = one_line_error(rls("study", sample_blends["t_junction"], "--traffic", "1-5",
                              "--evaluate", "10", "--out", tmp_path / "bad"))
    assert "not among the traffic frames" in line
    # the background used is said, and the evaluated vehicle-frames are too few: said
    assert ev["background"]["kind"] == "empty" and ev["background"]["sweeps"] == 5
    assert "background: each candidate's 5 sweeps of the scene" in proc.stderr
    assert f"hold {ev['vehicle_frames']} counted vehicle-frames" in proc.stderr
    assert set(ev["correlation_by_k"]) == {"1", "2"}


def test_one_evaluation_frame_scores_what_it_sees(sample_blends, tmp_path):
    """Issue 38/37: --evaluate 5 (one frame) made each candidate learn that very frame
    as its background and every placement scored 0. The empty scene's sweeps are the
    background now: the frame's vehicles are found."""
    out = tmp_path / "one"
    proc = rls("study", sample_blends["t_junction"], "--k", "1", "--mount", "TL NE",
               "--mount", "TL SW", "--pitch", "10", "--evaluate", "30", "--out", out)
    assert proc.returncode == 0, proc.stderr
    ev = json.loads((out / "study.json").read_text())["evaluation"]
    assert max(c["ap"] for c in ev["candidates"]) > 0.5


def test_study_rotation_hz_is_recorded(sample_blends, tmp_path):
    """A unit measured at 10.017 Hz: the study scans with it and says so."""
    out = tmp_path / "rate"
    proc = rls("study", sample_blends["four_lane"], "--mount", "SL N +0", "--k", "1",
               "--device", "hesai_pandarqt", "--rotation-hz", "10.017", "--out", out)
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "study.json").read_text())
    assert report["settings"]["rotation_hz"] == 10.017
    assert report["settings"]["lidar_mode"] is None
