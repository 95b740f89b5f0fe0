"""Rotation rates and lidar modes on the command line (issue #32): into the pattern,
into each scan's sidecar, and refused with one line when the device cannot run so."""

import json

from .conftest import one_line_error, rls


def test_pattern_at_a_measured_rate_and_a_lidar_mode(tmp_path):
    out = tmp_path / "qt.csv"
    proc = rls("pattern", "hesai_pandarqt", "--rotation-hz", "10.017", "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "38400 rays" in proc.stdout  # 600 firings x 64 channels, motor-locked
    out = tmp_path / "os.csv"
    proc = rls("pattern", "ouster_os1_64", "--lidar-mode", "2048x10", "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert f"{2048 * 64} rays" in proc.stdout
    line = one_line_error(rls("pattern", "hesai_pandarqt", "--rotation-hz", "20",
                              "--out", tmp_path / "bad.csv"))
    assert "rotation_hz 20 Hz" in line and "10 Hz" in line
    line = one_line_error(rls("pattern", "ouster_os1_64", "--lidar-mode", "4096x5",
                              "--out", tmp_path / "bad2.csv"))
    assert "4096x5" in line and "1024x10" in line


def test_presets_show_lists_modes():
    proc = rls("presets", "show", "ouster_os1_64")
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    assert info["modes"]["default_lidar_mode"] == "1024x10"


def test_scan_rotation_hz_round_trips_into_the_sidecar(demo_run, tmp_path):
    """The demo's LiDAR is a Pandar64 (10 or 20 Hz): a unit measured at 10.017 Hz."""
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "rate"
    proc = rls("scan", blend, "--frames", "5", "--out", out, "--rotation-hz", "10.017")
    assert proc.returncode == 0, proc.stderr
    side = json.loads((out / "intersection_LiDAR_000005.json").read_text())
    assert side["effects"]["rotation_hz"] == 10.017
    assert side["effects"]["lidar_mode"] is None
    line = one_line_error(rls("scan", blend, "--frames", "5", "--out", tmp_path / "bad",
                              "--rotation-hz", "15"))
    assert "rotation_hz 15 Hz" in line and "10, 20 Hz" in line
