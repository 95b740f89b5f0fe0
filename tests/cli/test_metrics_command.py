"""``rls metrics`` end to end: polygon file or .blend region, sidecar frames, errors."""

import json
import os
import struct
import subprocess
import sys

import numpy as np
import pytest

from rls_addon.core.output.io import write_cloud, write_sidecar
from rls_addon.core.output.png import decode_png_rgba
from rls_addon.core.points import empty_points, transform_points

from .conftest import ROOT, one_line_error, rls

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
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and "notice" not in proc.stderr
    # a chart (7.5 in at 100 dpi: axes, colour bar, title), not the 15 x 10 cell image
    assert struct.unpack(">II", data[16:24])[0] == 750


def test_density_png_without_matplotlib_is_the_bare_map_and_one_notice(tmp_path, polygon_file):
    blocked = tmp_path / "blocked" / "matplotlib"
    blocked.mkdir(parents=True)
    (blocked / "__init__.py").write_text("raise ImportError('matplotlib blocked for this test')\n")
    cloud = write_cloud(tmp_path / "c.pcd", grid(), "pcd_binary_compressed")
    png = tmp_path / "density.png"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(blocked.parent), str(ROOT)]))
    proc = subprocess.run([sys.executable, "-m", "rls_addon", "metrics", "--lob-polygon",
                           str(polygon_file), "--disks", "500", "--cell", "2", "--density-png",
                           str(png), str(cloud)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("rls: notice: matplotlib is not installed")
    assert json.loads(proc.stdout)["infra_d"] == 4.0
    img = decode_png_rgba(png.read_bytes())  # RLS's own writer: 34 pixels per 2 m cell
    assert img.shape == (15 * 34, 10 * 34, 4)


def test_density_chart_title_names_region_sensor_and_metrics(tmp_path, polygon_file):
    from argparse import Namespace

    from rls_addon.commands.metrics import chart_title
    from rls_addon.core.metrics.infra import infra_lob_metrics

    cloud = write_cloud(tmp_path / "c.pcd", grid(), "pcd_binary_compressed")
    write_sidecar(cloud, {"sensor": "Pole Lidar", "frame": 7, "frame_space": "world",
                          "device": {"id": "x", "name": "Hesai Pandar64"}})
    other = write_cloud(tmp_path / "plain.pcd", grid(), "pcd_binary_compressed")
    res = infra_lob_metrics([grid()], RECT, disks=100)
    title = chart_title(Namespace(lob_polygon=str(polygon_file), lob=None,
                                  clouds=[str(cloud), str(other)]), res)
    assert "Pole Lidar (Hesai Pandar64, frame 7) + plain" in title
    assert "region lob.json" in title and "InfraD 4.00 points / m²" in title
    assert f"InfraNUC {res.infra_nuc:.3f}" in title
    title = chart_title(Namespace(lob_polygon=None, lob="/x/intersection.blend:InfraLOB",
                                  clouds=[str(other)]), res)
    assert "region InfraLOB in intersection.blend" in title


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


def test_one_cloud_given_twice_is_refused(tmp_path, polygon_file):
    cloud = write_cloud(tmp_path / "c.pcd", grid(), "pcd_binary_compressed")
    again = tmp_path / "sub" / ".." / "c.pcd"
    (tmp_path / "sub").mkdir()
    line = one_line_error(rls("metrics", "--lob-polygon", polygon_file, cloud, again))
    assert "is the cloud" in line and "again: give each LiDAR's cloud once" in line


def test_bad_inputs_are_one_line_errors(tmp_path, polygon_file):
    bad = tmp_path / "bad.pcd"
    bad.write_bytes(b"nonsense")
    assert "bad.pcd" in one_line_error(rls("metrics", "--lob-polygon", polygon_file, bad))
    flat = tmp_path / "flat.json"
    flat.write_text("[[0, 0], [1, 1], [2, 2]]")
    cloud = write_cloud(tmp_path / "c.pcd", grid())
    assert "zero area" in one_line_error(rls("metrics", "--lob-polygon", flat, cloud))
    assert "not found" in one_line_error(rls("metrics", "--lob", tmp_path / "missing.blend:Lob", cloud))


def test_a_crossing_region_and_a_negative_disk_seed_are_one_line_errors(tmp_path,
                                                                        polygon_file):
    cloud = write_cloud(tmp_path / "c.pcd", grid())
    bow = tmp_path / "bow.json"
    bow.write_text("[[-12, -12], [12, 12], [12, -12], [-12, 6]]")
    assert one_line_error(rls("metrics", "--lob-polygon", bow, cloud)).startswith(
        "rls: error: the region's outline crosses itself at (-1.71429, -1.71429): ")
    line = one_line_error(rls("metrics", "--lob-polygon", polygon_file, "--seed=-1", cloud))
    assert line == "rls: error: the disk seed must be a whole number >= 0, got -1"


def test_density_chart_marks_the_sensors_of_the_clouds_sidecars(tmp_path, polygon_file):
    """Issue 31: the README promised sensor markers the chart did not draw."""
    from rls_addon.commands.metrics import sensor_markers

    yaw90 = np.array([[0.0, -1, 0, 10], [1, 0, 0, -4], [0, 0, 1, 6], [0, 0, 0, 1]])
    frames = []
    for f in (1, 2):  # one sensor over two frames: one marker, where its first sweep began
        cloud = write_cloud(tmp_path / f"pole_{f}.pcd", grid(), "pcd_binary_compressed")
        pose = yaw90.copy()
        pose[0, 3] += f
        write_sidecar(cloud, {"sensor": "Pole", "frame": f, "frame_space": "world",
                              "sensor_to_world": pose})
        frames.append(cloud)
    plain = write_cloud(tmp_path / "plain.pcd", grid(), "pcd_binary_compressed")
    (name, x, y, heading), = sensor_markers([*frames, plain])
    assert (name, x, y) == ("Pole", 11.0, -4.0) and heading == pytest.approx(90.0)

    def red_pixels(png):
        from matplotlib.image import imread  # matplotlib's chart PNGs use every filter

        img = imread(str(png))
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        return int(np.count_nonzero((r > 0.8) & (g < 0.15) & (b < 0.15)))

    pngs = {}
    for key, clouds in (("with", frames[:1]), ("without", [plain])):
        pngs[key] = tmp_path / f"{key}.png"
        proc = rls("metrics", "--lob-polygon", polygon_file, "--disks", 100, "--cell", 2,
                   "--density-png", pngs[key], *clouds)
        assert proc.returncode == 0, proc.stderr
    assert red_pixels(pngs["without"]) == 0 and red_pixels(pngs["with"]) > 30


def test_prints_the_numbers_and_the_grid_only_on_request(tmp_path, polygon_file):
    """The density map's values (a line per cell: about 700 lines on the sample
    intersection) once filled the output: they come with --grid, or whole in --out."""
    cloud = write_cloud(tmp_path / "c.pcd", grid(), "pcd_binary_compressed")
    plain = rls("metrics", "--lob-polygon", polygon_file, "--disks", 200, cloud)
    assert plain.returncode == 0, plain.stderr
    out = json.loads(plain.stdout)
    assert out["infra_d"] == 4.0 and "infra_nuc" in out
    assert "values" not in out["density"] and out["density"]["shape"] == [30, 20]
    assert len(plain.stdout.splitlines()) < 60
    full = rls("metrics", "--lob-polygon", polygon_file, "--disks", 200, "--grid", cloud)
    values = json.loads(full.stdout)["density"]["values"]
    assert len(values) == 30 and values[0][0] == 4.0
    result = tmp_path / "result.json"
    proc = rls("metrics", "--lob-polygon", polygon_file, "--disks", 200, "--out", result, cloud)
    assert proc.returncode == 0, proc.stderr
    saved = json.loads(result.read_text())
    assert saved["density"]["values"] == values and saved["infra_d"] == 4.0
    assert json.loads(proc.stdout)["result"] == str(result)
    line = one_line_error(rls("metrics", "--lob-polygon", polygon_file, "--out", result, cloud))
    assert "already exists" in line
    assert ".json" in one_line_error(rls("metrics", "--lob-polygon", polygon_file, "--out",
                                         tmp_path / "r.txt", cloud))
