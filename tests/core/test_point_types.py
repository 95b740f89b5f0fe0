"""Vendor point layouts: exact dtypes, unit conversions, and PCL's typed loader reading
each layout into the driver's own point struct."""

import numpy as np
import pytest

from rls_addon.core.errors import OutputError, SettingsError
from rls_addon.core.output.io import pcd
from rls_addon.core.output.io.point_types import (
    POINT_TYPE_CHOICES,
    POINT_TYPES,
    elevation_rings,
    point_type_dtype,
    point_type_fields,
    to_point_type,
)

from . import pcl_typed
from .cloud_samples import sample_cloud

# The drivers' definitions (docs/formats.md names the repository and path of each):
# field names, types and order, as PCL and PointCloud2 see them.
DRIVER_FIELDS = {
    "rls": [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"),
            ("time", "<f8"), ("label", "<u4"), ("instance", "<u4"), ("ghost", "u1")],
    "velodyne": [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"),
                 ("ring", "<u2"), ("time", "<f4")],
    "ouster": [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("t", "<u4"),
               ("reflectivity", "<u2"), ("ring", "<u2"), ("ambient", "<u2"), ("range", "<u4")],
    "hesai": [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2"),
              ("timestamp", "<f8")],
    "autoware": [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "u1"),
                 ("return_type", "u1"), ("channel", "<u2")],
}
START = 1_700_000_000.25  # an absolute sweep start (Unix seconds)
# A VLP-16's channel table in firing order: elevations interleave -15, 1, -13, 3, ...
VLP16_ELEVATIONS = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]


def _cloud(n=3000, seed=7, channels=16):
    p = sample_cloud(n, seed=seed)
    p["ring"] = np.arange(n) % channels
    p["intensity"][:3] = [0.0, 1.0, 0.5][:n]  # the ends of the scale and a rounding tie
    return p


def expected(p, name, start=0.0, elevations=None):
    """Each layout's values, written out from its documented units (not from the code)."""
    f32 = {f: p[f].astype(np.float32) for f in "xyz"}
    i = p["intensity"].astype(np.float64)
    ring = p["ring"].astype(np.int64)
    if elevations is not None:
        el = np.asarray(elevations, float)
        by_el = {"velodyne": np.argsort(np.argsort(el, kind="stable"), kind="stable"),
                 "ouster": np.argsort(np.argsort(-el, kind="stable"), kind="stable")}
        if name in by_el:
            ring = by_el[name][ring]
    cols = {
        "rls": [p["intensity"], p["ring"], p["time"], p["label"], p["instance"], p["ghost"]],
        "velodyne": [np.float32(i * 255), ring, p["time"].astype(np.float32)],
        "ouster": [np.float32(i * 255), np.rint(p["time"] * 1e9), np.rint(i * 100), ring,
                   np.zeros(len(p)), np.rint(p["range"] * 1000)],
        "hesai": [np.rint(i * 255), ring, start + p["time"]],
        "autoware": [np.rint(i * 255), np.ones(len(p)), ring],
    }[name]
    return np.column_stack([f32["x"], f32["y"], f32["z"]] + [np.asarray(c, np.float64) for c in cols])


def _as_rows(records):
    return np.column_stack([records[f].astype(np.float64) for f in records.dtype.names])


@pytest.mark.parametrize("name", POINT_TYPES)
def test_dtype_is_the_drivers_exact_packed_layout(name):
    dt = point_type_dtype(name)
    assert [(f, dt[f].str.replace("|", "")) for f in dt.names] == \
        [(f, t.replace("|", "")) for f, t in DRIVER_FIELDS[name]]
    assert dt.itemsize == sum(np.dtype(t).itemsize for _, t in DRIVER_FIELDS[name])  # packed
    assert [f.name for f in point_type_fields(name)] == list(dt.names)
    assert all(f.unit and f.value for f in point_type_fields(name))


@pytest.mark.parametrize("name", POINT_TYPES)
def test_conversion_units(name):
    p = _cloud(500)
    rec = to_point_type(p, name, start_time_s=START)
    assert rec.dtype == point_type_dtype(name)
    np.testing.assert_array_equal(_as_rows(rec), expected(p, name, START))


def test_intensity_scales_and_rounding():
    p = _cloud(3)
    assert list(to_point_type(p, "velodyne")["intensity"]) == [0.0, 255.0, 127.5]
    assert list(to_point_type(p, "hesai")["intensity"]) == [0.0, 255.0, 128.0]  # rint(127.5)
    assert list(to_point_type(p, "autoware")["intensity"]) == [0, 255, 128]
    assert list(to_point_type(p, "ouster")["reflectivity"]) == [0, 100, 50]


def test_out_of_range_values_are_clipped_not_wrapped():
    p = _cloud(3)
    p["intensity"] = [-0.5, 1.5, 1.0]
    p["time"] = [-1e-6, 0.1, 5.0]
    p["range"] = [-1.0, 1e7, 0.0005]
    o = to_point_type(p, "ouster")
    assert list(o["t"]) == [0, 100_000_000, 4_294_967_295]  # 5 s is beyond uint32 ns
    assert list(o["range"]) == [0, 4_294_967_295, 0]  # 0.5 mm rounds to even 0
    assert list(o["reflectivity"]) == [0, 100, 100]
    assert list(to_point_type(p, "autoware")["intensity"]) == [0, 255, 255]


def test_hesai_timestamps_are_absolute_and_keep_microseconds():
    p = _cloud(100)
    ts = to_point_type(p, "hesai", start_time_s=START)["timestamp"]
    np.testing.assert_allclose(ts - START, p["time"], rtol=0, atol=1e-6)
    assert (ts > START).sum() == (p["time"] > 0).sum()


def test_rings_by_elevation():
    # Velodyne numbers rings from the lowest beam up, Ouster from the top beam down
    rows = np.arange(16, dtype=np.uint16)
    vel = elevation_rings(rows, VLP16_ELEVATIONS, lowest_first=True)
    ous = elevation_rings(rows, VLP16_ELEVATIONS, lowest_first=False)
    assert list(vel) == [0, 8, 1, 9, 2, 10, 3, 11, 4, 12, 5, 13, 6, 14, 7, 15]
    assert list(ous) == [15 - r for r in vel]
    p = _cloud(64)
    rec = to_point_type(p, "velodyne", channel_elevations_deg=VLP16_ELEVATIONS)
    np.testing.assert_array_equal(rec["ring"], vel[p["ring"]])
    # hesai and autoware keep the table row (their drivers number lasers as the table does)
    np.testing.assert_array_equal(
        to_point_type(p, "autoware", channel_elevations_deg=VLP16_ELEVATIONS)["channel"], p["ring"])
    with pytest.raises(OutputError, match="outside the channel table"):
        elevation_rings(np.array([16], np.uint16), VLP16_ELEVATIONS)


def test_unknown_point_type_names_the_valid_ones():
    with pytest.raises(SettingsError) as err:
        to_point_type(_cloud(2), "livox")
    for name in POINT_TYPES:
        assert name in str(err.value)
    with pytest.raises(SettingsError):
        point_type_fields("Velodyne")
    assert POINT_TYPE_CHOICES.ids[0] == "rls"


def test_points_without_the_needed_fields_are_refused():
    rec = np.zeros(3, [("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
    with pytest.raises(OutputError, match="lack field"):
        to_point_type(rec, "ouster")


def test_empty_cloud():
    for name in POINT_TYPES:
        rec = to_point_type(_cloud(0), name, start_time_s=START)
        assert len(rec) == 0 and rec.dtype == point_type_dtype(name)


# PCL's typed loader reads each layout into the driver's struct -----------------------

@pytest.fixture(scope="module")
def pcl_reader(tmp_path_factory):
    return pcl_typed.build(tmp_path_factory.mktemp("pcl_typed"))


@pytest.mark.parametrize("encoding", pcd.ENCODINGS)
@pytest.mark.parametrize("name", POINT_TYPES)
def test_pcl_typed_loader_reads_every_field(tmp_path, pcl_reader, name, encoding):
    p = _cloud(3000, channels=16)
    path = tmp_path / f"{name}.pcd"
    path.write_bytes(pcd.encode(to_point_type(p, name, start_time_s=START,
                                              channel_elevations_deg=VLP16_ELEVATIONS), encoding))
    got = pcl_typed.read(pcl_reader, name, path)
    want = expected(p, name, START, VLP16_ELEVATIONS)
    assert got.shape == want.shape
    np.testing.assert_array_equal(got, want)
    # the sweep's times arrive, and the rings are those of the driver's numbering
    names = point_type_dtype(name).names
    time_col = next((names.index(f) for f in ("time", "t", "timestamp") if f in names), None)
    if time_col is not None:
        assert np.count_nonzero(got[:, time_col]) >= len(p) - 1
        assert np.unique(got[:, time_col]).size > len(p) // 2
    ring_col = names.index("channel" if name == "autoware" else "ring")
    assert sorted(np.unique(got[:, ring_col])) == list(range(16))


def test_pcl_typed_loader_reads_an_empty_cloud(tmp_path, pcl_reader):
    path = tmp_path / "empty.pcd"
    path.write_bytes(pcd.encode(to_point_type(_cloud(0), "ouster"), "binary"))
    assert pcl_typed.read(pcl_reader, "ouster", path).shape[0] == 0
