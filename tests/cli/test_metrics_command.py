"""``rls metrics`` end to end: polygon file or .blend region, sidecar frames, errors."""

import json

import numpy as np
import pytest

from rls_addon.core.io import write_cloud, write_sidecar
from rls_addon.core.png import decode_png_rgba
from rls_addon.core.points import empty_points, transform_points

from .conftest import one_line_error, rls

RECT = [[0, 0], [20, 0], [20, 30], [0, 30]]


def grid(spacing=0.5):
    gx, gy = np.meshgrid(np.arange(spacing / 2, 20, spacing), np.arange(spacing / 2, 30, spacing))
    p = empty_points(gx.size)
    p["x"], p["y"], p["label"] = gx.ravel(), gy.ravel(), 1
    return p


@pytest.fixture
def polygon_file(tmp_path):
    path = tmp_path / "lob.json"
    path.write_text(json.dumps({"polygon": RECT}))
    return path


def test_metrics_with_polygon_file_and_png(tmp_path, polygon_file):
    cloud = write_cloud(tmp_path / "c.pcd", grid(), "pcd_binary_compressed")
    png = tmp_path / "density.png"
    proc = rls("metrics", "--lob-polygon", polygon_file, "--disks", 500, "--cell", 2,
               "--density-png", png, cloud)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["infra_d"] == 4.0 and out["n_points"] == 2400 and out["disks"] == 500
    assert out["density"]["shape"] == [15, 10]
    assert decode_png_rgba(png.read_bytes()).shape[2] == 4


def test_sensor_frame_clouds_are_moved_to_world_by_their_sidecar(tmp_path, polygon_file):
    pose = np.eye(4)
    pose[:3, 3] = [100.0, -50.0, 6.0]
    world = grid()
    local = transform_points(world, np.linalg.inv(pose))
    cloud = write_cloud(tmp_path / "s.ply", local, "ply_binary")
    write_sidecar(cloud, {"frame": 3, "frame_space": "sensor", "sensor_to_world": pose})
    proc = rls("metrics", "--lob-polygon", polygon_file, "--disks", 200, cloud)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["n_points"] == 2400


def test_empty_region_is_one_line_error(tmp_path, polygon_file):
    far = grid()
    far["x"] += 1000
    cloud = write_cloud(tmp_path / "far.pcd", far)
    line = one_line_error(rls("metrics", "--lob-polygon", polygon_file, cloud))
    assert "holds no points" in line


def test_bad_inputs_are_one_line_errors(tmp_path, polygon_file):
    bad = tmp_path / "bad.pcd"
    bad.write_bytes(b"nonsense")
    assert "bad.pcd" in one_line_error(rls("metrics", "--lob-polygon", polygon_file, bad))
    flat = tmp_path / "flat.json"
    flat.write_text("[[0, 0], [1, 1], [2, 2]]")
    cloud = write_cloud(tmp_path / "c.pcd", grid())
    assert "zero area" in one_line_error(rls("metrics", "--lob-polygon", flat, cloud))
    assert "not found" in one_line_error(rls("metrics", "--lob", tmp_path / "missing.blend:Lob", cloud))
