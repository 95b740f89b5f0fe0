"""``python -m rls_addon presets ...`` and ``pattern ...`` as a user runs them."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def rls(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "rls_addon", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_presets_list():
    out = rls("presets", "list")
    assert out.returncode == 0, out.stderr
    for pid in ("velodyne_vlp16", "hesai_pandar128", "livox_mid40", "robosense_m1", "ouster_os1_64"):
        assert pid in out.stdout
    js = rls("presets", "list", "--json")
    ids = {p["id"] for p in json.loads(js.stdout)}
    assert len(ids) >= 24


def test_presets_list_names_a_broken_user_file_and_lists_the_rest(tmp_path):
    """Issue 31: one broken user preset stopped the listing with only its error."""
    text = (ROOT / "presets" / "generic_uniform32.toml").read_text()
    (tmp_path / "mine.toml").write_text(text.replace('id = "generic_uniform32"', 'id = "mine"'))
    (tmp_path / "broken.toml").write_text('schema = 1\nid = "broken"\nname = "B"\n')
    out = rls("presets", "list", "--user-dir", tmp_path)
    assert out.returncode == 1
    assert "mine" in out.stdout and "velodyne_vlp16" in out.stdout
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "broken.toml" in lines[0] and "family" in lines[0]


def test_presets_show():
    out = rls("presets", "show", "Livox Horizon")
    assert out.returncode == 0, out.stderr
    info = json.loads(out.stdout)
    assert info["id"] == "livox_horizon" and info["fitted"] is True and "FITTED" in info["source"]


def test_presets_validate_good_and_bad(tmp_path):
    good = ROOT / "presets" / "velodyne_vlp16.toml"
    out = rls("presets", "validate", good)
    assert out.returncode == 0 and "ok" in out.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text('id = "b"\nname = "B"\nfamily = "spinning"\nsource = "s"\nfrequency_hz = nan\n')
    out = rls("presets", "validate", bad)
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.toml" in lines[0] and "frequency_hz" in lines[0]


def test_unknown_preset_is_one_line_error(tmp_path):
    out = rls("pattern", "no-such-lidar", "--out", tmp_path / "x.csv")
    assert out.returncode == 1
    assert len(out.stderr.strip().splitlines()) == 1 and "no-such-lidar" in out.stderr


def test_pattern_csv_spans_frames(tmp_path):
    dest = tmp_path / "vlp16.csv"
    out = rls("pattern", "velodyne_vlp16", "--duration", "0.25", "--out", dest)
    assert out.returncode == 0, out.stderr
    with open(dest) as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "azimuth_deg", "elevation_deg", "channel"]
    a = np.array(rows[1:], dtype=float)
    assert np.all(np.diff(a[:, 0]) >= 0)
    assert 0.2499 < a[-1, 0] < 0.25
    # two whole frames of 1808 cycles x 16 lasers, then half a frame
    assert abs(len(a) - 2.5 * 16 * 1808) <= 16
    again = rls("pattern", "velodyne_vlp16", "--out", dest)
    assert again.returncode == 1 and "exists" in again.stderr


def test_pattern_risley_times_continue(tmp_path):
    dest = tmp_path / "mid40.csv"
    out = rls("pattern", "livox_mid40", "--duration", "0.3", "--out", dest)
    assert out.returncode == 0, out.stderr
    a = np.loadtxt(dest, delimiter=",", skiprows=1)
    assert len(a) == 30_000 and np.all(np.diff(a[:, 0]) > 0)
