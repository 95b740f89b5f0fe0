"""``rls study`` as users run it, on scenes written by sample_scenes/make_scenes.py."""

import csv
import json
import subprocess
import sys

import pytest

from .conftest import ROOT, one_line_error, rls


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
    assert report["hidden_traffic"] == ["Car east", "Car turning", "Car west"]
    assert report["placements"]["2"]["best_density"]["units"] == "points per square metre"
    pytest.importorskip("matplotlib")
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
])
def test_study_errors_are_one_line(sample_blends, tmp_path, args, message):
    proc = rls("study", sample_blends["t_junction"], "--out", tmp_path / "o", *args)
    assert message in one_line_error(proc)


def test_study_missing_scene(tmp_path):
    proc = rls("study", tmp_path / "missing.blend", "--out", tmp_path / "o")
    assert "scene file not found" in one_line_error(proc)
