"""LAS 1.4 files read back by laspy, by lazpy (an independent port of LASzip), by the
bytes of the public header as the ASPRS specification lays them out, and by PDAL's
``pdal info`` where PDAL is installed."""

import json
import shutil
import struct
import subprocess
import sys

import numpy as np
import pytest

from rls_addon.core.errors import OutputError, RLSError, SettingsError
from rls_addon.core.scene.instances import instance_id
from rls_addon.core.output.io.las import (
    ASPRS_CLASS,
    EXTRA_DIMS,
    GPS_EPOCH_UNIX,
    LasWriter,
    asprs_classes,
    gps_time,
)
from rls_addon.core.labels import DEFAULT_LABELS, NAME_TO_ID

from .cloud_samples import sample_cloud
from .external_tools import require_module

UNIX_2024 = 1_704_067_200.0  # 2024-01-01T00:00:00Z; GPS - UTC = 18 s then
# 2024-01-01 in GPS seconds: 1704067200 - 315964800 + 18 = 1388102418; adjusted: - 1e9
ADJUSTED_2024 = 388_102_418.0
WORLD = np.array([500_123.0, 5_400_456.0, 310.0])  # a UTM-like world origin


def world_cloud(n, seed, shift=WORLD):
    p = sample_cloud(n, seed=seed)
    for k, f in enumerate("xyz"):
        p[f] = p[f] + shift[k]
    p["label"] = np.arange(n) % len(DEFAULT_LABELS)
    ids = np.array([0] + [instance_id(f"obj{k}") for k in range(25)], dtype=np.uint32)
    p["instance"] = ids[np.arange(n) % ids.size]
    p["intensity"][:2] = [0.0, 1.0]
    return p


def two_sensors():
    a, b = world_cloud(1200, 1), world_cloud(800, 2)
    return [("roof", a, UNIX_2024 + 0.5), ("pole", b, UNIX_2024 + 0.6)]


def expected_columns(clouds, scale=1e-4, offset=None):
    pts = np.concatenate([p for _, p, _ in clouds])
    xyz = np.stack([pts[f] for f in "xyz"], axis=1)
    off = np.floor(xyz.min(axis=0) / 1000) * 1000 if offset is None else np.asarray(offset)
    q = np.rint((xyz - off) / scale)
    t = np.concatenate([t0 + p["time"] for _, p, t0 in clouds])
    return {
        "xyz": off + q * scale, "offset": off, "n": len(pts),
        "intensity": np.rint(pts["intensity"].astype(float) * 65535),
        "classification": np.array([ASPRS_CLASS[int(v)] for v in pts["label"]]),
        "gps_time": t - GPS_EPOCH_UNIX + 18 - 1e9,
        "ring": pts["ring"], "label": pts["label"], "instance": pts["instance"],
        "ghost": pts["ghost"],
    }


@pytest.fixture()
def las_file(tmp_path):
    clouds = two_sensors()
    path = LasWriter(["pole", "roof"], crs="EPSG:25832").write_merged(tmp_path / "f.las", clouds)
    return path, clouds


def test_asprs_table():
    named = {DEFAULT_LABELS[i]: c for i, c in ASPRS_CLASS.items()}
    assert named["road"] == 11 and named["building"] == 6 and named["water"] == 9
    assert named["ground"] == named["terrain"] == named["sidewalk"] == 2
    assert named["unlabeled"] == 1 and named["vegetation"] == 5
    assert named["vehicle"] == 64 + NAME_TO_ID["vehicle"]
    assert named["weather"] == 18  # false returns from the air: High Noise
    assert all(c in (1, 2, 5, 6, 9, 11, 18) or 64 <= c <= 255 for c in ASPRS_CLASS.values())
    assert list(asprs_classes([1, 11, 19, 20, 191, 192, 70000])) == [11, 75, 18, 84, 255, 1, 1]


def test_gps_time_conversion():
    t, standard = gps_time([UNIX_2024, UNIX_2024 + 0.25])
    assert standard and list(t) == [ADJUSTED_2024, ADJUSTED_2024 + 0.25]
    # 2016-12-31T23:59:59Z is before the 18th leap second (17 s), 2017-01-01T00:00:00Z on it
    t, _ = gps_time([1_483_228_799.0, 1_483_228_800.0])
    assert list(t) == [1_483_228_799.0 - GPS_EPOCH_UNIX + 17 - 1e9,
                       1_483_228_800.0 - GPS_EPOCH_UNIX + 18 - 1e9]
    t, _ = gps_time([float(GPS_EPOCH_UNIX)])  # the GPS epoch itself: GPS = UTC
    assert t[0] == -1e9
    rel, standard = gps_time([0.0, 12.5])  # a run without an absolute clock
    assert not standard and list(rel) == [0.0, 12.5]
    with pytest.raises(OutputError, match="cannot mix"):
        gps_time([1.0, UNIX_2024])


def test_laspy_reads_every_field(las_file):
    laspy = require_module("laspy", "laspy==2.7.0")
    path, clouds = las_file
    las = laspy.read(str(path))
    want = expected_columns(clouds)
    h = las.header
    assert (h.version.major, h.version.minor, h.point_format.id) == (1, 4, 6)
    assert h.point_count == want["n"] == 2000
    np.testing.assert_array_equal(h.offsets, want["offset"])
    np.testing.assert_allclose(np.stack([las.x, las.y, las.z], axis=1), want["xyz"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(h.mins, want["xyz"].min(axis=0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(h.maxs, want["xyz"].max(axis=0), rtol=0, atol=1e-9)
    for f in ("intensity", "classification", "gps_time", "ring", "label", "instance", "ghost"):
        np.testing.assert_array_equal(np.asarray(las[f]), want[f], err_msg=f)
    assert list(np.unique(las.point_source_id[:1200])) == [2]  # roof, second in the run
    assert list(np.unique(las.point_source_id[1200:])) == [1]  # pole
    assert set(las.return_number) == {1} and set(las.number_of_returns) == {1}
    assert int(h.global_encoding.gps_time_type) == 1
    assert h.parse_crs().to_epsg() == 25832
    assert h.creation_date.isoformat() == "2024-01-01"


def test_lazpy_reads_every_field(las_file):
    lazpy = require_module("lazpy", "lazpy==0.9.2")
    path, clouds = las_file
    want = expected_columns(clouds)
    r = lazpy.Reader(str(path))
    assert r.num_points == 2000 and r.point_format == 6
    assert r.scales == (1e-4, 1e-4, 1e-4) and r.offsets == tuple(want["offset"])
    a = r.arrays()
    xyz = np.stack([a["X"], a["Y"], a["Z"]], axis=1) * 1e-4 + want["offset"]
    np.testing.assert_allclose(xyz, want["xyz"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(a["intensity"], want["intensity"])
    np.testing.assert_array_equal(a["extended_classification"], want["classification"])
    np.testing.assert_array_equal(a["gps_time"], want["gps_time"])
    np.testing.assert_array_equal(a["point_source_ID"], [2] * 1200 + [1] * 800)
    extra = _extra_bytes(path.read_bytes(), a["extra_bytes"])
    for f in ("ring", "label", "instance", "ghost"):
        np.testing.assert_array_equal(extra[f], want[f], err_msg=f)
    assert "25832" in str(r.crs)


def _extra_bytes(blob, raw):
    """Columns of the points' extra bytes (N, k) uint8, decoded from the file's Extra
    Bytes VLR (user id LASF_Spec, record 4; 192-byte descriptors) per LAS 1.4."""
    header_size, = struct.unpack_from("<H", blob, 94)
    n_vlr, = struct.unpack_from("<I", blob, 100)
    pos, sizes = header_size, {1: "u1", 2: "i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4",
                               7: "<u8", 8: "<i8", 9: "<f4", 10: "<f8"}
    for _ in range(n_vlr):
        user = blob[pos + 2:pos + 18].rstrip(b"\0")
        rid, length = struct.unpack_from("<HH", blob, pos + 18)
        if (user, rid) == (b"LASF_Spec", 4):
            fields = []
            for k in range(length // 192):
                d = pos + 54 + 192 * k
                data_type = blob[d + 2]
                name = blob[d + 4:d + 36].rstrip(b"\0").decode()
                fields.append((name, sizes[data_type]))
            return np.ascontiguousarray(raw).view(np.dtype(fields))[:, 0]
        pos += 54 + length
    raise AssertionError("no Extra Bytes VLR")


def test_public_header_bytes_follow_the_spec(las_file):
    path, clouds = las_file
    blob = path.read_bytes()
    want = expected_columns(clouds)
    assert blob[:4] == b"LASF"
    enc, = struct.unpack_from("<H", blob, 6)
    assert enc & 1 and enc & 16  # adjusted standard GPS time; WKT CRS
    assert blob[24:26] == bytes([1, 4])
    header_size, offset_to_points = struct.unpack_from("<HI", blob, 94)
    assert header_size == 375
    fmt, rec_len, legacy_count = struct.unpack_from("<BHI", blob, 104)
    assert fmt == 6 and rec_len == 30 + sum(np.dtype(t).itemsize for _, t, _ in EXTRA_DIMS)
    assert legacy_count == 0  # must be zero for point formats 6-10
    scales_offsets = struct.unpack_from("<6d", blob, 131)
    assert scales_offsets[:3] == (1e-4,) * 3 and scales_offsets[3:] == tuple(want["offset"])
    maxx, minx, maxy, miny, maxz, minz = struct.unpack_from("<6d", blob, 179)
    np.testing.assert_allclose([minx, miny, minz], want["xyz"].min(axis=0), rtol=0, atol=1e-9)
    np.testing.assert_allclose([maxx, maxy, maxz], want["xyz"].max(axis=0), rtol=0, atol=1e-9)
    count, = struct.unpack_from("<Q", blob, 247)
    by_return = struct.unpack_from("<15Q", blob, 255)
    assert count == 2000 and by_return[0] == 2000 and sum(by_return) == 2000
    assert len(blob) == offset_to_points + count * rec_len


def test_pdal_info_reads_counts_bounds_and_classes(las_file):
    # PDAL is not packaged in Debian 12 (bookworm) nor installable from PyPI (its
    # bindings build against libpdal); where a 'pdal' command exists, it must agree.
    exe = shutil.which("pdal")
    if exe is None:
        pytest.skip("PDAL's 'pdal' command is missing: Debian 12 has no pdal package; "
                    "install PDAL's command-line tool to run this check")
    path, clouds = las_file
    want = expected_columns(clouds)
    summary = json.loads(subprocess.run([exe, "info", "--summary", str(path)], check=True,
                                        capture_output=True, text=True, timeout=120).stdout)
    s = summary["summary"]
    assert s["num_points"] == 2000
    b = s["bounds"]
    np.testing.assert_allclose([b["minx"], b["miny"], b["minz"]], want["xyz"].min(axis=0), atol=1e-6)
    np.testing.assert_allclose([b["maxx"], b["maxy"], b["maxz"]], want["xyz"].max(axis=0), atol=1e-6)
    for dim in ("ring", "label", "instance", "ghost"):
        assert dim in s["dimensions"]
    stats = json.loads(subprocess.run(
        [exe, "info", "--stats", "--enumerate", "Classification", str(path)], check=True,
        capture_output=True, text=True, timeout=120).stdout)
    cls = next(d for d in stats["stats"]["statistic"] if d["name"] == "Classification")
    assert sorted(int(v) for v in cls["values"]) == sorted(set(want["classification"].tolist()))


def test_one_file_per_cloud_with_a_fixed_offset(tmp_path):
    laspy = require_module("laspy", "laspy==2.7.0")
    w = LasWriter(["roof", "pole"], offset=WORLD - 500, scale=0.001)
    for sensor, pts, t0 in two_sensors():
        path = w.write(tmp_path / f"{sensor}_000001.las", sensor, pts, t0)
        las = laspy.read(str(path))
        want = expected_columns([(sensor, pts, t0)], scale=0.001, offset=WORLD - 500)
        assert las.header.point_count == len(pts)
        np.testing.assert_array_equal(las.header.offsets, WORLD - 500)
        np.testing.assert_allclose(np.stack([las.x, las.y, las.z], axis=1), want["xyz"], atol=1e-9)
        assert set(las.point_source_id) == {w.source_id(sensor)}
        assert las.header.parse_crs() is None


def test_relative_clock_is_written_as_week_time(tmp_path):
    laspy = require_module("laspy", "laspy==2.7.0")
    pts = world_cloud(100, 3)
    path = LasWriter(["s"]).write(tmp_path / "rel.las", "s", pts, 2.5)
    las = laspy.read(str(path))
    assert int(las.header.global_encoding.gps_time_type) == 0
    np.testing.assert_array_equal(las.gps_time, 2.5 + pts["time"])


def test_existing_files_and_overflow_leave_nothing_behind(tmp_path):
    w = LasWriter(["s"])
    pts = world_cloud(10, 4)
    path = w.write(tmp_path / "a.las", "s", pts, UNIX_2024)
    before = path.read_bytes()
    with pytest.raises(OutputError, match="already exists"):
        w.write(path, "s", pts, UNIX_2024)
    assert path.read_bytes() == before
    far = world_cloud(10, 5)
    far["x"][3] = WORLD[0] + 300_000.0  # beyond int32 * 0.1 mm from the offset
    with pytest.raises(OutputError, match="do not fit"):
        LasWriter(["s"], offset=WORLD).write(tmp_path / "b.las", "s", far, UNIX_2024)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.las"]
    with pytest.raises(SettingsError, match="unknown sensor"):
        w.write(tmp_path / "c.las", "other", pts, UNIX_2024)
    # a NaN offset (or point) is refused, not written as X = -2^31 for every point
    with pytest.raises(OutputError, match="do not fit"):
        LasWriter(["s"], offset=(np.nan, *WORLD[1:])).write(tmp_path / "d.las", "s", pts,
                                                          UNIX_2024)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.las"]


@pytest.mark.parametrize("offset", [(np.nan, 0.0, 0.0), (0.0, np.inf, 0.0)])
def test_a_las_offset_that_is_not_finite_is_a_settings_error(offset):
    from rls_addon.core.scan.settings import OutputSettings

    with pytest.raises(SettingsError, match="LAS offset.*finite"):
        OutputSettings(format="las", las_offset=offset)


def test_settings_errors():
    with pytest.raises(SettingsError, match="EPSG"):
        LasWriter(["s"], crs="UTM32")
    with pytest.raises(SettingsError, match="unknown CRS"):
        LasWriter(["s"], crs="EPSG:999999")
    with pytest.raises(SettingsError, match="positive"):
        LasWriter(["s"], scale=0)
    with pytest.raises(SettingsError, match="repeat"):
        LasWriter(["s", "s"])


def test_missing_laspy_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "laspy", None)  # import laspy now raises ImportError
    with pytest.raises(RLSError, match="pip install laspy"):
        LasWriter(["s"]).write(tmp_path / "x.las", "s", world_cloud(3, 6), UNIX_2024)
    assert not (tmp_path / "x.las").exists()


def test_missing_pyproj_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyproj", None)
    with pytest.raises(RLSError, match="pip install pyproj"):
        LasWriter(["s"], crs="EPSG:25832")
