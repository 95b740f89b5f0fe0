"""Property tests: every format reads back what was written, for any cloud."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rls_addon.core.errors import InputError
from rls_addon.core.output.io import (
    DEFAULT_FIELDS,
    encode_cloud,
    read_cloud,
    write_cloud,
)
from rls_addon.core.output.io import lzf
from rls_addon.core.output.io.formats import FORMATS as ALL_FORMATS
from rls_addon.core.output.io.cloud import read_records
from rls_addon.core.points import empty_points

from .cloud_samples import stored
from .external_tools import require_module

# The formats of files of point records (PCD, PLY): what write_cloud writes
FORMATS = [f.id for f in ALL_FORMATS if f.encode is not None]
finite32 = st.floats(-1e6, 1e6, allow_nan=False, width=32)


@st.composite
def clouds(draw, max_n=60):
    n = draw(st.integers(0, max_n))
    p = empty_points(n)
    for f in ("x", "y", "z"):
        p[f] = draw(hnp.arrays(np.float32, n, elements=finite32))
    p["intensity"] = draw(hnp.arrays(np.float32, n, elements=st.floats(0, 1, width=32)))
    p["ring"] = draw(hnp.arrays(np.uint16, n))
    p["time"] = draw(hnp.arrays(np.float64, n, elements=st.floats(-1e3, 1e3, allow_nan=False)))
    p["label"] = draw(hnp.arrays(np.uint32, n))
    p["instance"] = draw(hnp.arrays(np.uint32, n))
    p["ghost"] = draw(hnp.arrays(np.uint8, n, elements=st.integers(0, 1)))
    return p


SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("fmt", FORMATS)
@SETTINGS
@given(points=clouds())
def test_round_trip_through_our_reader(tmp_path, fmt, points):
    path = write_cloud(tmp_path / "c.cloud", points, fmt, overwrite=True)
    back = read_cloud(path)
    assert len(back) == len(points)
    for field in DEFAULT_FIELDS:
        np.testing.assert_array_equal(back[field], stored(points, field), err_msg=field)
    assert not back["range"].any()  # not stored by default


@pytest.mark.parametrize("fmt", ["ply_ascii", "ply_binary"])
@SETTINGS
@given(points=clouds())
def test_round_trip_through_plyfile(tmp_path, fmt, points):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    path = write_cloud(tmp_path / "c.ply", points, fmt, overwrite=True)
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    assert vertex.count == len(points)
    for field in DEFAULT_FIELDS:
        np.testing.assert_array_equal(vertex[field], stored(points, field), err_msg=field)


@pytest.mark.parametrize("fmt", FORMATS)
@SETTINGS
@given(points=clouds(), fields=st.sets(st.sampled_from(["range", "intensity", "ring", "time", "label", "instance", "ghost"])),
       time_dtype=st.sampled_from(["float64", "float32"]))
def test_field_subsets_and_float32_time(tmp_path, fmt, points, fields, time_dtype):
    points["range"] = np.abs(points["x"])
    path = write_cloud(tmp_path / "c.cloud", points, fmt, fields=sorted(fields), time_dtype=time_dtype, overwrite=True)
    rec = read_records(path)
    assert rec.dtype.names[:3] == ("x", "y", "z")
    assert set(rec.dtype.names) == {"x", "y", "z"} | fields
    if "time" in fields:
        assert rec.dtype["time"].itemsize == (8 if time_dtype == "float64" else 4)
        np.testing.assert_array_equal(rec["time"], stored(points, "time", time_dtype))


@settings(max_examples=200, deadline=None)
@given(data=st.one_of(
    st.binary(max_size=3000),
    st.lists(st.sampled_from([b"\0", b"ab", b"abc", b"\x01\x00\x00\x00", b"xyz12"]), max_size=800).map(b"".join),
))
def test_lzf_round_trip(data):
    packed = lzf.compress(data)
    assert lzf.decompress(packed, len(data)) == data


def test_lzf_compresses_repetitive_columns():
    labels = np.repeat(np.arange(10, dtype="<u4"), 10_000).tobytes()
    packed = lzf.compress(labels, [(0, len(labels), (4, 8))])
    assert len(packed) < len(labels) / 50
    assert lzf.decompress(packed, len(labels)) == labels


def test_lzf_rejects_corrupt_stream():
    with pytest.raises(InputError):
        lzf.decompress(bytes([0x20, 0x05]), 3)  # back reference before start
    with pytest.raises(InputError):
        lzf.decompress(bytes([5, 1, 2]), 6)  # literal run past end


def test_empty_cloud_encodes_header_only():
    for fmt in FORMATS:
        blob = encode_cloud(empty_points(0), fmt)
        assert b"0" in blob
        assert len(read_cloud_bytes(blob)) == 0


def read_cloud_bytes(blob):
    from rls_addon.core.output.io import pcd, ply

    return ply.decode(blob) if blob.startswith(b"ply") else pcd.decode(blob)
