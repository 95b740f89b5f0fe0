"""``rls presets import-calibration`` then ``rls pattern``, as a user runs them: every
angle of the calibration file comes back in the pattern CSV (which prints degrees to 6
decimals and times to 1 ns: 2.5e-6 deg with the head's turn taken off, finer than the
0.001-0.0001 deg the Hesai, Ouster and RoboSense files print)."""

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.cli.conftest import one_line_error, rls

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.core.test_calibration_import import FIX, expected  # noqa: E402
from rls_addon.core.device.angle_tables import AZIMUTH_CONVENTIONS  # noqa: E402

CASES = [
    ("hesai_sdk2_pandar64.csv", "hesai_pandar64", 10.0),
    ("nebula_pandarxt32.csv", "hesai_pandarxt32", 10.0),
    ("velodyne_ros_vlp32c.yaml", "velodyne_vlp32c", 10.0),
    ("velodyne_ros_32db.xml", "velodyne_hdl32e", 10.0),
    ("ouster_3_0_1_os-122246000293-128.json", "ouster_os1_128", 10.0),
    ("robosense_ros_rs32_angle.csv", "robosense_rs32", 10.0),
]


@pytest.mark.parametrize("name,base,hz", CASES, ids=[c[0] for c in CASES])
def test_import_then_pattern_reproduces_every_angle(tmp_path, name, base, hz):
    user = tmp_path / "user"
    proc = rls("presets", "import-calibration", FIX / name, "--base", base, "--id", "unit",
               "--user-dir", user)
    assert proc.returncode == 0, proc.stderr
    assert "imported 'unit'" in proc.stdout
    out = tmp_path / "p.csv"
    proc = rls("pattern", "unit", "--user-dir", user, "--out", out)
    assert proc.returncode == 0, proc.stderr
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    el_want, az_raw, vendor = expected(name)
    first = {}
    for r in rows:
        first.setdefault(int(r["channel"]), r)
    assert sorted(first) == list(range(len(el_want)))
    t = np.array([float(first[k]["time_s"]) for k in sorted(first)])
    el = np.array([float(first[k]["elevation_deg"]) for k in sorted(first)])
    az = np.array([float(first[k]["azimuth_deg"]) for k in sorted(first)]) + 360.0 * hz * t
    np.testing.assert_allclose(el, el_want, rtol=0, atol=5.01e-7)
    d = (az - AZIMUTH_CONVENTIONS[vendor] * np.asarray(az_raw) + 180.0) % 360.0 - 180.0
    assert np.abs(d).max() < 2.5e-6


def test_bad_calibration_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "dup.csv"
    bad.write_text("Laser id,Elevation,Azimuth\n" + "".join(
        f"{min(i, 39)},{i * 0.1},0\n" for i in range(1, 41)))
    line = one_line_error(rls("presets", "import-calibration", bad, "--base", "hesai_pandar40p",
                              "--id", "u", "--user-dir", tmp_path / "user"))
    assert "dup.csv line 41: duplicate channel id 39 (also on line 40)" in line
    line = one_line_error(rls("presets", "import-calibration", FIX / "nebula_pandar64.csv",
                              "--base", "hesai_pandar40p", "--id", "u",
                              "--user-dir", tmp_path / "user"))
    assert "the file has 64 channels, base preset 'hesai_pandar40p' has 40" in line
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00\xff\x10garbage")
    line = one_line_error(rls("presets", "import-calibration", junk, "--base", "hesai_pandar40p",
                              "--id", "u", "--user-dir", tmp_path / "user"))
    assert "junk.bin: not a text file" in line and "Ouster sensor metadata JSON" in line
    assert not (tmp_path / "user" / "u.toml").exists()
