"""Our PCD and PLY files as Open3D, plyfile and PCL's command-line tools read them."""

import subprocess

import numpy as np
import pytest

from rls_addon.core.output.io import (
    DEFAULT_FIELDS,
    FORMATS,
    read_cloud,
    read_records,
    write_cloud,
)

from .cloud_samples import sample_cloud, stored
from .external_tools import require_exe, require_module

PCD_FORMATS = ("pcd_ascii", "pcd_binary", "pcd_binary_compressed")
PLY_FORMATS = ("ply_ascii", "ply_binary")
N = 2000


@pytest.fixture(scope="module")
def points():
    return sample_cloud(N, seed=42)


def _write(tmp_path, points, fmt, **kw):
    return write_cloud(tmp_path / f"cloud{FORMATS.get(fmt).extension}", points, fmt, **kw)


def _xyz(points):
    return np.stack([stored(points, f) for f in "xyz"], axis=1)


@pytest.mark.parametrize("fmt", PCD_FORMATS + PLY_FORMATS)
def test_open3d_legacy_reads_count_and_xyz(tmp_path, points, fmt):
    o3d = require_module("open3d", "open3d==0.20.0")
    path = _write(tmp_path, points, fmt)
    pc = o3d.io.read_point_cloud(str(path))
    got = np.asarray(pc.points)
    assert got.shape == (N, 3)
    np.testing.assert_array_equal(got.astype(np.float32), _xyz(points))


@pytest.mark.parametrize("fmt", PCD_FORMATS)
def test_open3d_tensor_reads_every_pcd_attribute(tmp_path, points, fmt):
    o3d = require_module("open3d", "open3d==0.20.0")
    path = _write(tmp_path, points, fmt)
    pc = o3d.t.io.read_point_cloud(str(path))
    np.testing.assert_array_equal(pc.point.positions.numpy(), _xyz(points))
    expect_dtypes = {"intensity": np.float32, "ring": np.uint16, "time": np.float64,
                     "label": np.uint32, "instance": np.uint32, "ghost": np.uint8}
    for field, dtype in expect_dtypes.items():
        col = pc.point[field].numpy()
        assert col.dtype == dtype, field
        np.testing.assert_array_equal(col[:, 0], stored(points, field), err_msg=field)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_open3d_tensor_reads_ply_float_and_uchar_attributes(tmp_path, points, fmt):
    # Open3D 0.20's tensor PLY reader skips ushort and uint properties (it warns
    # "unsupported datatype"); plyfile checks those below.
    o3d = require_module("open3d", "open3d==0.20.0")
    path = _write(tmp_path, points, fmt)
    pc = o3d.t.io.read_point_cloud(str(path))
    np.testing.assert_array_equal(pc.point.positions.numpy(), _xyz(points))
    for field in ("intensity", "time", "ghost"):
        np.testing.assert_array_equal(pc.point[field].numpy()[:, 0], stored(points, field), err_msg=field)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
@pytest.mark.parametrize("n", [0, 1, N])
def test_plyfile_reads_every_property_with_its_type(tmp_path, fmt, n):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    pts = sample_cloud(n, seed=n)
    path = _write(tmp_path, pts, fmt)
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    assert vertex.count == n
    types = {p.name: p.val_dtype for p in vertex.properties}
    # PLY keeps label and instance as int32, which every tested reader keeps (fields.py)
    assert types == {"x": "f4", "y": "f4", "z": "f4", "intensity": "f4", "ring": "u2",
                     "time": "f8", "label": "i4", "instance": "i4", "ghost": "u1"}
    for field in DEFAULT_FIELDS:
        np.testing.assert_array_equal(vertex[field], stored(pts, field), err_msg=field)


def test_plyfile_reads_float32_time_and_field_subset(tmp_path, points):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    path = _write(tmp_path, points, "ply_binary", fields=["time", "label"], time_dtype="float32")
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    assert [p.name for p in vertex.properties] == ["x", "y", "z", "time", "label"]
    np.testing.assert_array_equal(vertex["time"], points["time"].astype(np.float32))


def _pcl_to_ascii(src, dst):
    exe = require_exe("pcl_convert_pcd_ascii_binary")
    run = subprocess.run([exe, str(src), str(dst), "0"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    assert dst.exists(), run.stdout + run.stderr
    return run.stdout + run.stderr


@pytest.mark.parametrize("fmt", PCD_FORMATS)
def test_pcl_converts_our_pcd_to_ascii_with_same_values(tmp_path, points, fmt):
    path = _write(tmp_path, points, fmt)
    log = _pcl_to_ascii(path, tmp_path / "pcl_ascii.pcd")
    assert f"{N} points" in log
    back = read_records(tmp_path / "pcl_ascii.pcd")
    assert len(back) == N
    # PCL prints 7 significant digits: relative rounding error <= 5e-7
    for field in ("x", "y", "z", "intensity", "time"):
        np.testing.assert_allclose(back[field], stored(points, field), rtol=1e-6, atol=1e-12, err_msg=field)
    for field in ("ring", "label", "instance", "ghost"):
        np.testing.assert_array_equal(back[field], stored(points, field), err_msg=field)


@pytest.mark.parametrize("fmt", PCD_FORMATS)
def test_pcl_pcd2ply_output_read_by_plyfile(tmp_path, points, fmt):
    exe = require_exe("pcl_pcd2ply")
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    path = _write(tmp_path, points, fmt)
    out = tmp_path / "pcl.ply"
    run = subprocess.run([exe, str(path), str(out)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and out.exists(), run.stdout + run.stderr
    vertex = plyfile.PlyData.read(str(out))["vertex"]
    assert vertex.count == N
    for field in DEFAULT_FIELDS:
        np.testing.assert_array_equal(vertex[field], stored(points, field), err_msg=field)


@pytest.mark.parametrize("fmt", PCD_FORMATS)
def test_pcl_reads_empty_pcd(tmp_path, fmt):
    # PCL loads an empty cloud (warning "No points to read") but then refuses
    # to write it ("Input point cloud has no data!"), so only the load is checked.
    exe = require_exe("pcl_pcd2ply")
    path = _write(tmp_path, sample_cloud(0), fmt)
    run = subprocess.run([exe, str(path), str(tmp_path / "pcl.ply")], capture_output=True, text=True, timeout=60)
    log = run.stdout + run.stderr
    assert run.returncode == 0, log
    assert ": 0 points]" in log, log
    assert "Available dimensions: x y z intensity ring time label instance ghost" in log, log


def test_our_reader_decodes_pcl_binary_compressed(tmp_path, points):
    """PCL's own LZF stream (hash-table matcher) through our decompressor."""
    exe = require_exe("pcl_convert_pcd_ascii_binary")
    path = _write(tmp_path, points, "pcd_binary")
    out = tmp_path / "pcl_compressed.pcd"
    run = subprocess.run([exe, str(path), str(out), "2"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and out.exists(), run.stdout + run.stderr
    assert b"DATA binary_compressed" in out.read_bytes()[:400]
    back = read_cloud(out)
    for field in DEFAULT_FIELDS:
        np.testing.assert_array_equal(back[field], stored(points, field), err_msg=field)
