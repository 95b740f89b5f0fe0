"""``import-calibration``: a unit's calibration file as a user preset (issue 32).

Every fixture (tests/fixtures/calibration, real files the vendors' and Autoware's drivers
ship; see its README) is read back independently here (csv / json / yaml / a regex over
the XML) and each channel's elevation and azimuth offset must come out of the imported
preset's pattern to 1e-9 deg (finer than any file prints). Broken copies are refused
with one clear error naming the file and line.
"""

import csv
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from rls_addon.core.device.angle_tables import AZIMUTH_CONVENTIONS, read_angle_table
from rls_addon.core.device.calibration_files import read_calibration
from rls_addon.core.device.calibration_import import import_calibration
from rls_addon.core.device.patterns.base import angles_from_directions
from rls_addon.core.device.presets import builtin_presets_dir, get_preset
from rls_addon.core.device.user_presets import delete_user_preset, user_presets
from rls_addon.core.errors import OutputError, PresetError

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "calibration"

# The VLP-16 user manual's Table 9-1 "vertical correction" (mm) of laser ids 0-15: the
# offset of each laser from the sensor origin (www.easymanua.ls/velodyne/vlp-16/manual
# page 54 shows ids 7-15; ids 0-6 mirror them by elevation).
VLP16_MANUAL_MM = [11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2,
                   -9.7, 0.7, -11.2]

# fixture -> (base preset, vendor convention)
FIXTURES = {
    "hesai_sdk2_pandar64.csv": "hesai_pandar64",
    "hesai_sdk2_pandar40p.csv": "hesai_pandar40p",
    "hesai_sdk2_pandarqt.csv": "hesai_pandarqt",
    "hesai_sdk2_pandarxt32.csv": "hesai_pandarxt32",
    "nebula_pandar64.csv": "hesai_pandar64",
    "nebula_pandar40p.csv": "hesai_pandar40p",
    "nebula_pandarxt32.csv": "hesai_pandarxt32",
    "nebula_pandarqt64.csv": "hesai_pandarqt",
    "velodyne_ros_vlp16db.yaml": "velodyne_vlp16",
    "velodyne_ros_vlp16db_offsets.yaml": "velodyne_vlp16",
    "velodyne_ros_32db.yaml": "velodyne_hdl32e",
    "velodyne_ros_vlp32c.yaml": "velodyne_vlp32c",
    "velodyne_ros_64e_utexas.yaml": "velodyne_hdl64e",
    "nebula_vlp16.yaml": "velodyne_vlp16",
    "nebula_hdl64e_s3.yaml": "velodyne_hdl64e",
    "velodyne_ros_32db.xml": "velodyne_hdl32e",
    "velodyne_ros_64e_s2.1-sztaki.xml": "velodyne_hdl64e",
    "ouster_2_1_2_os1-991913000010-64.json": "ouster_os1_64",
    "ouster_2_1_2_os1-991913000010-64_legacy.json": "ouster_os1_64",
    "ouster_1_12_os1-991913000010-64.json": "ouster_os1_64",
    "ouster_OS-1-128_v2.3.0_1024x10.json": "ouster_os1_128",
    "ouster_3_0_1_os-122246000293-128.json": "ouster_os1_128",
    "robosense_ros_rs16_angle.csv": "robosense_rs16",
    "robosense_ros_rs32_angle.csv": "robosense_rs32",
    "robosense_ros_bpearl_angle.csv": "robosense_bpearl",
    "nebula_robosense_bpearl.csv": "robosense_bpearl",
}


def expected(name):
    """(elevations, vendor azimuth offsets, vendor) in degrees, in table order, read
    here without RLS's reader."""
    text = (FIX / name).read_text(encoding="utf-8-sig")
    if name.endswith(".yaml"):
        import yaml

        lasers = sorted(yaml.safe_load(text)["lasers"], key=lambda d: d["laser_id"])
        return ([math.degrees(d["vert_correction"]) for d in lasers],
                [math.degrees(d["rot_correction"]) for d in lasers], "velodyne")
    if name.endswith(".xml"):
        enabled = re.search(r"<enabled_>(.*?)</enabled_>", text, re.S).group(1)
        flags = [int(x) for x in re.findall(r"<item>(\d+)</item>", enabled)]
        px = re.findall(r"<id_>(\d+)</id_>\s*<rotCorrection_>([^<]+)</rotCorrection_>\s*"
                        r"<vertCorrection_>([^<]+)</vertCorrection_>", text)
        px = sorted((int(i), float(r), float(v)) for i, r, v in px if flags[int(i)])
        return [v for _, _, v in px], [r for _, r, _ in px], "velodyne"
    if name.endswith(".json"):
        d = json.loads(text)
        d = d.get("beam_intrinsics", d)
        return d["beam_altitude_angles"], d["beam_azimuth_angles"], "ouster"
    rows = [r for r in csv.reader(io.StringIO(text)) if r]
    if name.startswith("robosense") or name == "nebula_robosense_bpearl.csv":
        return ([float(r[0]) for r in rows], [float(r[1]) if len(r) > 1 else 0.0 for r in rows],
                "robosense")
    rows = sorted(rows[1:], key=lambda r: int(r[0]))
    return [float(r[1]) for r in rows], [float(r[2]) for r in rows], "hesai"


def first_rays(preset):
    """Per table row: the elevation and the azimuth offset (ccw, degrees) of the
    channel's first ray, the head's turn during its firing taken off."""
    pat = preset.pattern()
    az, el = angles_from_directions(pat.directions)
    c = len(preset.table.elevations_deg)
    first = np.array([np.flatnonzero(pat.channels == k)[0] for k in range(c)])
    head = -360.0 * preset.frequency_hz * pat.times[first]
    return np.degrees(el[first]), np.degrees(az[first]) - head


def wrapped(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_every_angle_of_the_fixture_comes_back(name, tmp_path):
    base = FIXTURES[name]
    p = import_calibration(FIX / name, base, "unit_x", tmp_path)
    el_want, az_raw, vendor = expected(name)
    assert p.scan["azimuth_convention"] == vendor
    assert len(p.table.elevations_deg) == len(el_want)
    el, az = first_rays(p)
    np.testing.assert_allclose(el, el_want, rtol=0, atol=1e-9)
    az_want = AZIMUTH_CONVENTIONS[vendor] * np.asarray(az_raw, float)
    assert np.abs(wrapped(az - az_want)).max() < 1e-9
    # the table itself holds the file's values bit for bit
    assert list(p.table.elevations_deg) == [float(v) for v in el_want]
    # everything else is the base's
    b = get_preset(base)
    assert (p.frequency_hz, p.range, p.dropout, p.rays_per_frame) == \
        (b.frequency_hz, b.range, b.dropout, b.rays_per_frame)
    kept = {k: v for k, v in b.scan.items()
            if k not in ("table", "beam_origins_m", "firing_times", "firing_time_zero_us")}
    if b.firing_times is not None:  # the base's firing times, by channel, inlined
        kept["firing_offsets_us"] = b.firing_times.offsets_us(
            list(p.table.channel_ids), b.scan.get("firing_time_zero_us", 0.0))
    assert {k: v for k, v in p.scan.items() if k != "table"} == kept
    assert (p.detection is None) == (b.detection is None)
    assert len(p.pattern()) == len(b.pattern())
    np.testing.assert_array_equal(p.pattern().times, b.pattern().times)
    # the source names the file and its sha256
    import hashlib

    assert name in p.source and hashlib.sha256((FIX / name).read_bytes()).hexdigest() in p.source
    assert base in p.source and b.source[:60] in p.source


@pytest.mark.parametrize("name,table", [
    ("hesai_sdk2_pandar64.csv", "hesai_pandar64.csv"),
    ("hesai_sdk2_pandarqt.csv", "hesai_pandarqt.csv"),
    ("velodyne_ros_vlp16db_offsets.yaml", "velodyne_vlp16.csv"),
    ("velodyne_ros_64e_utexas.yaml", "velodyne_hdl64e_s2_utexas.csv"),
    ("ouster_2_1_2_os1-991913000010-64.json", "ouster_os1_64.csv"),
    ("ouster_OS-1-128_v2.3.0_1024x10.json", "ouster_os1_128.csv"),
    ("robosense_ros_rs32_angle.csv", "robosense_rs32.csv"),
    ("robosense_ros_bpearl_angle.csv", "robosense_bpearl.csv"),
])
def test_the_shipped_tables_are_what_import_reads_from_their_sources(name, table):
    """The shipped tables were copied by hand from the same files: the reader agrees (to
    the 6 decimals the Velodyne tables print their converted radians)."""
    cal = read_calibration(FIX / name)
    t = read_angle_table(builtin_presets_dir() / "tables" / table)
    tol = 5.0001e-7 if name.endswith(".yaml") else 1e-12
    np.testing.assert_allclose(cal.elevations_deg, t.elevations_deg, rtol=0, atol=tol)
    np.testing.assert_allclose(cal.azimuth_offsets_deg, t.azimuth_offsets_deg, rtol=0, atol=tol)
    assert cal.channel_ids == t.channel_ids
    if t.origins_m is not None:  # per-beam origins, as the reader works them out
        np.testing.assert_allclose(cal.origins_m, t.origins_m, rtol=0, atol=1e-15)


def test_beam_origins_read_from_the_files():
    # Ouster: the ring radius (mm), flat, nested, from the transform, and the SDK default
    for name, mm in (("ouster_2_1_2_os1-991913000010-64.json", 12.163),
                     ("ouster_2_1_2_os1-991913000010-64_legacy.json", 12.163),
                     ("ouster_OS-1-128_v2.3.0_1024x10.json", 15.806),
                     ("ouster_3_0_1_os-122246000293-128.json", 16.721),
                     ("ouster_1_12_os1-991913000010-64.json", 15.806)):
        cal = read_calibration(FIX / name)
        assert set(cal.origins_m) == {(mm * 1e-3, 0.0, 0.0)}, name
    # Velodyne: the HDL-64E's two blocks sit 20 cm apart; nominal files have no offsets
    cal = read_calibration(FIX / "nebula_hdl64e_s3.yaml")
    z = np.array(cal.origins_m)[:, 2]
    assert 0.19 < z.max() < 0.22 and z.min() < 0.15
    assert read_calibration(FIX / "velodyne_ros_vlp16db.yaml").origins_m is None
    # ... but the VLP-16's since ros-drivers/velodyne #518 carries its lasers' offsets
    cal = read_calibration(FIX / "velodyne_ros_vlp16db_offsets.yaml")
    o, w = np.array(cal.origins_m), np.radians(cal.elevations_deg)
    np.testing.assert_allclose(np.linalg.norm(o, axis=1), np.abs(VLP16_MANUAL_MM) * 1e-3,
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(o[:, 2], np.array(VLP16_MANUAL_MM) * 1e-3 * np.cos(w),
                               rtol=0, atol=1e-15)
    xml = read_calibration(FIX / "velodyne_ros_64e_s2.1-sztaki.xml")
    assert xml.origins_m is not None and len(xml.origins_m) == 64
    # db.xml in centimetres: laser 0 of the sztaki unit: vertOffsetCorrection_ 19.548199
    v, w = 0.19548199, math.radians(-8.7686234)
    assert math.isclose(math.hypot(xml.origins_m[0][0], xml.origins_m[0][1]) ** 2
                        + xml.origins_m[0][2] ** 2, v * v + 0.025999999 ** 2, rel_tol=1e-9)
    assert math.isclose(xml.origins_m[0][2], v * math.cos(w), rel_tol=1e-9)


def test_stored_as_a_user_preset_with_its_table(tmp_path):
    p = import_calibration(FIX / "nebula_pandar64.csv", "hesai_pandar64", "my_p64", tmp_path,
                           name="My Pandar64")
    assert (tmp_path / "my_p64.toml").is_file() and (tmp_path / "tables" / "my_p64.csv").is_file()
    assert p.name == "My Pandar64" and p.scan["table"] == "tables/my_p64.csv"
    head = (tmp_path / "tables" / "my_p64.csv").read_text().splitlines()[0]
    assert head.startswith("# source: nebula_pandar64.csv (sha256 ")
    assert "my_p64" in user_presets(tmp_path)
    assert get_preset("my_p64", tmp_path).table.elevations_deg[0] == 14.9
    with pytest.raises(OutputError, match="already exists"):
        import_calibration(FIX / "nebula_pandar64.csv", "hesai_pandar64", "my_p64", tmp_path)
    with pytest.raises(OutputError, match="not a folder"):
        import_calibration(FIX / "nebula_pandar64.csv", "hesai_pandar64", "my_p64",
                           tmp_path / "tables" / "my_p64.csv")
    import_calibration(FIX / "hesai_sdk2_pandar64.csv", "hesai_pandar64", "my_p64", tmp_path,
                       overwrite=True)
    assert get_preset("my_p64", tmp_path).table.elevations_deg[0] == 14.708
    delete_user_preset("my_p64", tmp_path)
    assert not (tmp_path / "tables" / "my_p64.csv").exists()
    with pytest.raises(PresetError, match="built-in preset id"):
        import_calibration(FIX / "nebula_pandar64.csv", "hesai_pandar64", "hesai_pandar64",
                           tmp_path)


# ---- refused files: one clear error each ----------------------------------------------

HESAI_OK = "Channel,Elevation,Azimuth\n" + "".join(f"{i},{10 - i * 0.5},1.0\n"
                                                   for i in range(1, 41))


def _hesai(lines):
    return "Channel,Elevation,Azimuth\n" + "".join(lines)


def _rows(n=40, **change):
    rows = [f"{i},{10 - i * 0.5},1.0\n" for i in range(1, n + 1)]
    for k, v in change.items():
        rows[int(k[1:]) - 1] = v
    return rows


BAD = [
    # (file name, text, base, message pattern)
    ("short.csv", _hesai(_rows(39)), "hesai_pandar40p",
     r"short\.csv: the file has 39 channels, base preset 'hesai_pandar40p' has 40"),
    ("nan.csv", _hesai(_rows(r5="5,nan,1.0\n")), "hesai_pandar40p",
     r"nan\.csv line 6: elevation must be finite, got nan"),
    ("inf.csv", _hesai(_rows(r7="7,3.0,inf\n")), "hesai_pandar40p",
     r"inf\.csv line 8: azimuth must be finite, got inf"),
    ("dup.csv", _hesai(_rows(r40="3,1.0,1.0\n")), "hesai_pandar40p",
     r"dup\.csv line 41: duplicate channel id 3 \(also on line 4\)"),
    ("cols.csv", _hesai(_rows(r2="2,9.0\n")), "hesai_pandar40p",
     r"cols\.csv line 3: expected channel, elevation and azimuth, got '2,9.0'"),
    ("range.csv", _hesai(_rows(r9="9,95.0,1.0\n")), "hesai_pandar40p",
     r"range\.csv line 10: elevation 95.0 deg of channel 9 is outside -90..90"),
    ("word.csv", _hesai(_rows(r4="4,abc,1.0\n")), "hesai_pandar40p",
     r"word\.csv line 5: elevation must be a number, got 'abc'"),
    ("header.csv", "Channel,Elev,Azimuth\n" + "".join(_rows()), "hesai_pandar40p",
     r"header\.csv line 1: header must be 'Channel,Elevation,Azimuth'"),
    ("unknown.txt", "hello world\nthis is no calibration\n", "hesai_pandar40p",
     r"unknown\.txt: not a calibration format RLS recognises; accepted: Hesai angle-correction"),
    ("family.csv", HESAI_OK, "velodyne_hdl32e",
     r"family\.csv: the file is a Hesai angle-correction CSV.*base preset 'velodyne_hdl32e' "
     r"is a velodyne device"),
    ("mems.csv", HESAI_OK, "livox_avia", r"mems\.csv: base preset 'livox_avia' is a risley"),
    ("gap.csv", _hesai(_rows(r40="41,1.0,1.0\n")), "hesai_pandar40p",
     r"gap\.csv line 41: channel ids must run 1..40; 40 is missing"),
    ("nolaser.yaml", "lasers:\n- {laser_id: 0, rot_correction: 0.0}\n", "velodyne_vlp16",
     r"nolaser\.yaml line 2: laser 0 has no 'vert_correction'"),
    ("nanlaser.yaml", "lasers:\n" + "".join(
        f"- {{laser_id: {i}, rot_correction: 0.0, vert_correction: {'.nan' if i == 3 else 0.1}}}\n"
        for i in range(16)), "velodyne_vlp16",
     r"nanlaser\.yaml line 5: vert_correction must be finite, got nan"),
    ("duplaser.yaml", "lasers:\n" + "".join(
        f"- {{laser_id: {min(i, 14)}, rot_correction: 0.0, vert_correction: 0.1}}\n"
        for i in range(16)), "velodyne_vlp16",
     r"duplaser\.yaml line 17: duplicate channel id 14 \(also on line 16\)"),
    ("entity.xml", '<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY a "b">]>\n<x>&a;</x>\n',
     "velodyne_hdl32e", r"entity\.xml: XML with entity declarations or an internal DTD is refused"),
    ("other.xml", "<boost_serialization><DB></DB></boost_serialization>", "velodyne_hdl32e",
     r"other\.xml: not a Velodyne db.xml \(no DB/points_\)"),
    ("noazi.json", '{"beam_altitude_angles": [1, 2]}', "ouster_os1_64",
     r"noazi\.json: no 'beam_azimuth_angles': not an Ouster metadata file"),
    ("short.json", json.dumps({"beam_altitude_angles": [1.0] * 63,
                               "beam_azimuth_angles": [0.0] * 63}), "ouster_os1_64",
     r"short\.json: the file has 63 channels, base preset 'ouster_os1_64' has 64"),
    ("nanbeam.json", '{"beam_altitude_angles": [1.0, NaN],\n"beam_azimuth_angles": [0, 0]}',
     "ouster_os1_64", r"nanbeam\.json line 1: beam_altitude_angles\[1\] must be finite"),
    ("rows.csv", "".join(f"{i}.5,0.1\n" for i in range(31)) + "3.0\n", "robosense_rs32",
     r"rows\.csv line 32: expected 2 columns like the first row, got 1"),
    # what the decoders raise besides their own errors: RecursionError, ValueError
    ("deep.json", '{"beam_altitude_angles": ' + "[" * 100_000 + "]" * 100_000 + "}",
     "ouster_os1_64", r"deep\.json: not a readable JSON file \(nested too deeply\)"),
    ("bigint.json", '{"beam_altitude_angles": [' + "1" * 5000 + '], "beam_azimuth_angles": [0]}',
     "ouster_os1_64", r"bigint\.json: not a readable JSON file \(Exceeds the limit"),
    ("deep.yaml", "lasers: " + "[" * 100_000 + "]" * 100_000 + "\n", "velodyne_vlp16",
     r"deep\.yaml: not a readable YAML file \(nested too deeply\)"),
    ("bigint.yaml", "lasers:\n- {laser_id: " + "1" * 5000 + ", rot_correction: 0.0, "
     "vert_correction: 0.1}\n", "velodyne_vlp16",
     r"bigint\.yaml: not a readable YAML file \(Exceeds the limit"),
]


@pytest.mark.parametrize("name,text,base,pattern", BAD, ids=[b[0] for b in BAD])
def test_bad_files_are_refused_with_one_clear_error(tmp_path, name, text, base, pattern):
    f = tmp_path / name
    f.write_text(text, encoding="utf-8")
    with pytest.raises(PresetError) as err:
        import_calibration(f, base, "unit_x", tmp_path / "user")
    msg = str(err.value)
    assert re.search(pattern, msg), msg
    assert "\n" not in msg
    assert not (tmp_path / "user" / "unit_x.toml").exists()


def test_a_bad_id_is_refused(tmp_path):
    with pytest.raises(PresetError, match="--id must be lower-case"):
        import_calibration(FIX / "nebula_pandar64.csv", "hesai_pandar64", "Bad Id", tmp_path)


@pytest.mark.parametrize("name,base", [("nebula_hdl64e_s3.yaml", "velodyne_hdl64e"),
                                       ("ouster_3_0_1_os-122246000293-128.json", "ouster_os1_128")])
def test_export_keeps_the_beam_origins(tmp_path, name, base):
    from rls_addon.core.device.presets import load_preset
    from rls_addon.core.device.user_presets import export_preset

    p = import_calibration(FIX / name, base, "unit_x", tmp_path / "user")
    assert p.table.origins_m is not None
    dest = export_preset(p, tmp_path / "share" / "unit_x.toml")
    q = load_preset(dest)
    assert q.table is None and len(q.scan["beam_origins_m"]) == len(p.table.origins_m)
    a, b = p.pattern(), q.pattern()
    np.testing.assert_array_equal(a.origins, b.origins)
    np.testing.assert_array_equal(a.directions, b.directions)
