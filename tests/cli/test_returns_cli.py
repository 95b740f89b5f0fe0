"""``rls scan --return-mode dual``: a box edge in front of a wall sends two echoes back
on the beams that straddle it, written as ``return_index`` / ``num_returns`` in the PCD;
``--footprint off`` gives thin rays again, and the sidecar records both."""

import subprocess
import sys

import numpy as np
import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, rls

BUILD = SCENE_SCRIPT_HEAD + r"""
scene = bpy.context.scene
scene.name = "edge"

# a box whose vertical edges stand in the Mid-40's field of view, a wall 10 m behind
box("Box", (20, -3, -3), (22, 3, 3), 0.5, "car")
box("Wall", (32, -40, -30), (33, 40, 30), 0.5, "wall")
lidar = bpy.data.objects.new("LiDAR", None)
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id, s.noise = True, "livox_mid40", False
s.file_format = "pcd_binary"
s.fields = {"intensity", "range", "label", "return_index", "num_returns"}
s.output_dir = sys.argv[3]
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def edge_blend(tmp_path_factory):
    d = tmp_path_factory.mktemp("edge")
    blend = d / "edge.blend"
    proc = subprocess.run([sys.executable, "-c", BUILD, str(ROOT), str(blend), str(d / "panel")],
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return blend


def _scan(blend, out, *flags):
    proc = rls("scan", blend, "--frames", "1", "--out", out, *flags)
    assert proc.returncode == 0, proc.stderr[-3000:]
    from rls_addon.core.output.io import read_cloud, read_sidecar

    cloud = out / "edge_LiDAR_000001.pcd"
    header = cloud.read_bytes().split(b"\nDATA")[0].decode()
    return read_cloud(cloud), read_sidecar(cloud), header


def test_dual_returns_are_written_and_read_back(edge_blend, tmp_path):
    pts, side, header = _scan(edge_blend, tmp_path / "dual", "--return-mode", "dual")
    fields = next(line for line in header.splitlines() if line.startswith("FIELDS")).split()
    assert "return_index" in fields and "num_returns" in fields
    two = pts["num_returns"] == 2
    assert np.count_nonzero(two) >= 2, side["footprint"]
    assert set(np.unique(pts["return_index"])) == {1, 2}
    # a pulse's two echoes: the box first, the wall about 10 m behind
    first = pts[two & (pts["return_index"] == 1)]
    second = pts[two & (pts["return_index"] == 2)]
    assert len(first) == len(second)
    assert np.all(first["label"] != second["label"])
    assert np.all(second["range"] - first["range"] > 9.0)
    assert np.all(pts["num_returns"][~two] == 1) and np.all(pts["return_index"][~two] == 1)
    assert side["effects"]["return_mode"] == "dual" and side["effects"]["footprint"] == "auto"
    beam = side["device"]["beam"]
    assert beam["model"] == "footprint" and beam["divergence_rad"] == [0.00089, 0.00089]
    assert beam["return_mode"] == "dual"
    assert side["footprint"]["second_returns"] == len(second)

    thin, thin_side, _ = _scan(edge_blend, tmp_path / "thin", "--return-mode", "dual",
                               "--footprint", "off")
    assert np.all(thin["num_returns"] == 1) and np.all(thin["return_index"] == 1)
    assert thin_side["device"]["beam"]["model"] == "thin_ray"
    # the same pulses, plus the second echoes (give or take the few edge pulses whose
    # detection changed with the light they hold)
    assert abs(len(pts) - len(second) - len(thin)) <= 0.01 * len(thin)
