"""User scan-pattern CSV files."""

import numpy as np
import pytest

from rls_addon.core.errors import PatternError, PresetError
from rls_addon.core.device.patterns.base import angles_from_directions
from rls_addon.core.device.patterns.custom import read_pattern_csv, write_pattern_csv
from rls_addon.core.device.presets import load_preset


def test_round_trip(tmp_path):
    t = np.array([0.0, 0.001, 0.001, 0.002])
    az = np.array([10.0, -20.0, 30.0, 179.0])
    el = np.array([0.0, 5.0, -5.0, 45.0])
    ch = np.array([0, 1, 2, 3])
    f = tmp_path / "p.csv"
    write_pattern_csv(f, t, az, el, ch)
    pat = read_pattern_csv(f, frequency_hz=10.0)
    a, e = angles_from_directions(pat.directions)
    assert np.allclose(np.degrees(a), az, atol=1e-6) and np.allclose(np.degrees(e), el, atol=1e-6)
    assert np.array_equal(pat.channels, ch) and np.allclose(pat.times, t)
    assert pat.period == pytest.approx(0.1)


def test_headerless_three_columns_and_comments(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("# my pattern\n0,0,0\n\n0.5,10,1\n")
    pat = read_pattern_csv(f)
    assert len(pat) == 2 and list(pat.channels) == [0, 0]
    assert pat.period == pytest.approx(1.0)


@pytest.mark.parametrize("body,line,what", [
    ("time_s,azimuth_deg,elevation_deg\n0,0,0\n0.1,abc,0\n", 3, "azimuth_deg"),
    ("0,0,0\n0.1,0,nan\n", 2, "finite"),
    ("0,0,0\n0.1,0\n", 2, "columns"),
    ("0.2,0,0\n0.1,0,0\n", 2, "non-decreasing"),
    ("0,0,95\n", 1, "elevation_deg"),
    ("0,0,0,1.5\n", 1, "channel"),
    ("-1,0,0\n", 1, "time_s"),
    ("time,x,y\n", 1, "header"),
])
def test_bad_content_names_file_and_line(tmp_path, body, line, what):
    f = tmp_path / "bad.csv"
    f.write_text(body)
    with pytest.raises(PatternError) as exc:
        read_pattern_csv(f)
    msg = str(exc.value)
    assert "bad.csv" in msg and f"line {line}" in msg and what in msg


def test_missing_and_empty(tmp_path):
    with pytest.raises(PatternError, match="not found"):
        read_pattern_csv(tmp_path / "nope.csv")
    (tmp_path / "e.csv").write_text("# nothing\n")
    with pytest.raises(PatternError, match="no rays"):
        read_pattern_csv(tmp_path / "e.csv")


def test_times_beyond_frame_rejected(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("0,0,0\n0.2,0,0\n")
    with pytest.raises(PatternError, match="frame period"):
        read_pattern_csv(f, frequency_hz=10.0)


def test_custom_family_preset(tmp_path):
    (tmp_path / "patterns").mkdir()
    (tmp_path / "patterns" / "mine.csv").write_text("0,0,0,0\n0.01,1,2,3\n")
    (tmp_path / "mine.toml").write_text(
        'id = "mine"\nname = "Mine"\nfamily = "custom"\nsource = "my own file"\n'
        'frequency_hz = 10.0\n[range]\nmax_m = 50.0\n[scan]\nfile = "patterns/mine.csv"\n')
    p = load_preset(tmp_path / "mine.toml")
    assert len(p.pattern()) == 2
    (tmp_path / "evil.toml").write_text(
        'id = "evil"\nname = "E"\nfamily = "custom"\nsource = "x"\n'
        'frequency_hz = 10.0\n[range]\nmax_m = 50.0\n[scan]\nfile = "../mine.csv"\n')
    with pytest.raises(PresetError, match="evil.toml.*'file'"):
        load_preset(tmp_path / "evil.toml")
