"""Which PLY property types each reader keeps, and that RLS's PLY files use only types
every tested reader keeps (docs/formats.md records the table these tests establish).

Readers: Open3D 0.20's tensor reader, plyfile, PCL (pcl_ply2pcd, Debian pcl-tools) and
CloudCompare 2.11 in command-line mode (Debian cloudcompare, headless with Qt's
offscreen platform)."""

import glob
import os
import subprocess

import numpy as np
import pytest

from rls_addon.core.scene.instances import instance_id
from rls_addon.core.output.io import DEFAULT_FIELDS, read_records, write_cloud
from rls_addon.core.output.io import ply as ply_mod

from .cloud_samples import sample_cloud, stored
from .external_tools import require_exe, require_module

PLY_FORMATS = ("ply_ascii", "ply_binary")
ENCODING = {"ply_ascii": "ascii", "ply_binary": "binary_little_endian"}
N = 1500

# Property type -> does Open3D 0.20's tensor reader keep it (measured by the first test)
OPEN3D_KEEPS = {"char": False, "uchar": True, "short": False, "ushort": False, "int": True,
                "uint": False, "float": True, "double": True, "int8": False, "uint8": True,
                "int16": False, "uint16": True, "int32": True, "uint32": False,
                "float32": True, "float64": True}
NUMPY = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4",
         "uint": "<u4", "float": "<f4", "double": "<f8", "int8": "i1", "uint8": "u1",
         "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4", "float32": "<f4",
         "float64": "<f8"}


def scan_like(n=N, seed=3):
    """A cloud with the values a scan makes: table labels, 31-bit instance hashes."""
    p = sample_cloud(n, seed=seed)
    p["label"] = np.arange(n) % 19
    ids = np.array([0] + [instance_id(f"object{k}") for k in range(40)], dtype=np.uint32)
    p["instance"] = ids[np.arange(n) % ids.size]
    return p


def _typed_ply(path, encoding, ptype, values):
    """A PLY file with x y z and one property ``v`` of PLY type ``ptype``."""
    rec = np.zeros(len(values), [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("v", NUMPY[ptype])])
    rec["x"] = np.arange(len(values))
    rec["v"] = values
    head = (f"ply\nformat {encoding} 1.0\nelement vertex {len(rec)}\nproperty float x\n"
            f"property float y\nproperty float z\nproperty {ptype} v\nend_header\n").encode()
    body = rec.tobytes() if encoding != "ascii" else ("\n".join(
        " ".join(repr(v) for v in row) for row in rec.tolist()) + "\n").encode()
    path.write_bytes(head + body)
    return rec


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("ptype", sorted(OPEN3D_KEEPS))
def test_which_types_open3d_tensor_reader_keeps(tmp_path, encoding, ptype):
    o3d = require_module("open3d", "open3d==0.20.0")
    dt = np.dtype(NUMPY[ptype])
    hi = np.iinfo(dt).max if dt.kind in "iu" else 1.5
    lo = np.iinfo(dt).min if dt.kind in "iu" else -2.5
    rec = _typed_ply(tmp_path / "t.ply", encoding, ptype, [0, 1, 2, hi, lo])
    pc = o3d.t.io.read_point_cloud(str(tmp_path / "t.ply"))
    kept = "v" in pc.point
    assert kept == OPEN3D_KEEPS[ptype], f"Open3D {'keeps' if kept else 'skips'} {ptype}"
    if kept:
        got = pc.point["v"].numpy()[:, 0]
        assert got.dtype == dt
        np.testing.assert_array_equal(got, rec["v"])


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("ptype", sorted(OPEN3D_KEEPS))
def test_plyfile_and_pcl_keep_every_type(tmp_path, encoding, ptype):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    exe = require_exe("pcl_ply2pcd")
    dt = np.dtype(NUMPY[ptype])
    hi = np.iinfo(dt).max if dt.kind in "iu" else 1.5
    lo = np.iinfo(dt).min if dt.kind in "iu" else -2.5
    rec = _typed_ply(tmp_path / "t.ply", encoding, ptype, [0, 1, 2, hi, lo])
    vertex = plyfile.PlyData.read(str(tmp_path / "t.ply"))["vertex"]
    assert vertex["v"].dtype == dt
    np.testing.assert_array_equal(vertex["v"], rec["v"])
    run = subprocess.run([exe, str(tmp_path / "t.ply"), str(tmp_path / "t.pcd")],
                         capture_output=True, text=True, timeout=60, check=False)
    assert run.returncode == 0, run.stdout + run.stderr
    back = read_records(tmp_path / "t.pcd")
    assert back.dtype["v"] == dt
    np.testing.assert_array_equal(back["v"], rec["v"])


def test_rls_ply_uses_only_types_open3d_keeps(tmp_path):
    path = write_cloud(tmp_path / "c.ply", scan_like(), "ply_binary",
                       fields=DEFAULT_FIELDS + ("range",))
    head = path.read_bytes().split(b"end_header")[0].decode().splitlines()
    types = {line.split()[2]: line.split()[1] for line in head if line.startswith("property")}
    assert types == {"x": "float", "y": "float", "z": "float", "range": "float",
                     "intensity": "float", "ring": "uint16", "time": "double", "label": "int",
                     "instance": "int", "ghost": "uchar"}
    assert all(OPEN3D_KEEPS[t] for t in types.values())


@pytest.mark.parametrize("time_dtype", ["float64", "float32"])
@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_open3d_tensor_reader_keeps_every_field(tmp_path, fmt, time_dtype):
    o3d = require_module("open3d", "open3d==0.20.0")
    p = scan_like()
    fields = DEFAULT_FIELDS + ("range",)
    path = write_cloud(tmp_path / "c.ply", p, fmt, fields=fields, time_dtype=time_dtype)
    pc = o3d.t.io.read_point_cloud(str(path))
    np.testing.assert_array_equal(pc.point.positions.numpy(),
                                  np.stack([stored(p, f) for f in "xyz"], axis=1))
    assert sorted(pc.point) == sorted(["positions"] + [f for f in fields if f not in "xyz"])
    for f in fields[3:]:
        got = pc.point[f].numpy()[:, 0]
        np.testing.assert_array_equal(got, stored(p, f, time_dtype), err_msg=f)
    assert pc.point["ring"].numpy().dtype == np.uint16
    assert pc.point["label"].numpy().dtype == np.int32


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_plyfile_keeps_every_field(tmp_path, fmt):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    p = scan_like()
    path = write_cloud(tmp_path / "c.ply", p, fmt, fields=DEFAULT_FIELDS + ("range",))
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    assert vertex.count == N
    for f in DEFAULT_FIELDS + ("range",):
        np.testing.assert_array_equal(vertex[f], stored(p, f), err_msg=f)
    assert {q.name: q.val_dtype for q in vertex.properties}["ring"] == "u2"


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_pcl_keeps_every_field(tmp_path, fmt):
    exe = require_exe("pcl_ply2pcd")
    p = scan_like()
    path = write_cloud(tmp_path / "c.ply", p, fmt, fields=DEFAULT_FIELDS + ("range",))
    out = tmp_path / "pcl.pcd"
    run = subprocess.run([exe, str(path), str(out)], capture_output=True, text=True, timeout=60,
                         check=False)
    assert run.returncode == 0 and out.exists(), run.stdout + run.stderr
    back = read_records(out)  # PCL parsed the PLY; its PCD is plain binary
    assert back.dtype["ring"] == np.dtype("<u2") and back.dtype["label"] == np.dtype("<i4")
    for f in DEFAULT_FIELDS + ("range",):
        np.testing.assert_array_equal(back[f], stored(p, f), err_msg=f)


def _cloudcompare_ascii(exe, path, workdir):
    """CloudCompare's ASCII export of ``path`` (written beside it): column names, rows."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", HOME=str(workdir))
    run = subprocess.run([exe, "-SILENT", "-O", str(path), "-C_EXPORT_FMT", "ASC",
                          "-ADD_HEADER", "-PREC", "12", "-SAVE_CLOUDS"],
                         capture_output=True, text=True, timeout=120, cwd=workdir, env=env,
                         check=False)
    found = glob.glob(str(path.parent / "*.asc"))
    assert run.returncode == 0 and len(found) == 1, run.stdout[-3000:] + run.stderr[-3000:]
    with open(found[0]) as fh:
        names = fh.readline().lstrip("/").split()
    return names, np.loadtxt(found[0], comments="//", ndmin=2)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_cloudcompare_command_line_keeps_xyz_and_intensity(tmp_path, fmt):
    # CloudCompare 2.11's PLY import without its dialog (-SILENT) loads coordinates and
    # the properties it recognises by name (intensity; 'scalar_*'), whatever their type:
    # ring, time, label, instance, ghost and range need its interactive dialog.
    exe = require_exe("CloudCompare", "cloudcompare")
    p = scan_like()
    path = write_cloud(tmp_path / "cc" / "c.ply", p, fmt, fields=DEFAULT_FIELDS + ("range",))
    names, table = _cloudcompare_ascii(exe, path, tmp_path)
    assert names[:3] == ["X", "Y", "Z"] and "intensity" in names, names
    assert table.shape[0] == N
    for k, f in enumerate("xyz"):
        np.testing.assert_allclose(table[:, k], stored(p, f), rtol=0, atol=1e-9, err_msg=f)
    np.testing.assert_allclose(table[:, names.index("intensity")], stored(p, "intensity"),
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_uint32_values_beyond_int32_stay_uint32_and_exact(tmp_path, fmt):
    plyfile = require_module("plyfile", "plyfile==1.0.3")
    p = scan_like(50)
    p["instance"][7] = 2**32 - 1
    path = write_cloud(tmp_path / "c.ply", p, fmt)
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    types = {q.name: q.val_dtype for q in vertex.properties}
    assert types["instance"] == "u4" and types["label"] == "i4"
    np.testing.assert_array_equal(vertex["instance"], p["instance"])
    assert read_records(path)["instance"][7] == 2**32 - 1


def test_ply_encoder_keeps_other_columns_and_empty_clouds():
    rec = np.zeros(0, [("x", "<f4"), ("n", "<u4"), ("k", "<u2")])
    head = ply_mod.encode(rec, "binary_little_endian")
    assert b"property int n\n" in head and b"property uint16 k\n" in head
