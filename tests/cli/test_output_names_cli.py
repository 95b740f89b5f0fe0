"""Output names are decided before any work: file names two LiDARs share, a template
without {frame} over several frames and existing files end the run at once, with one
line, nothing scanned and nothing written."""

import subprocess
import sys

import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, one_line_error, rls

BUILD = SCENE_SCRIPT_HEAD + r"""
scene = bpy.context.scene
scene.name = "names"
box("Wall", (10, -10, -3), (11, 10, 3), 0.5, "wall")
for name, y in (("Лидар 1", 0.0), ("Радар 1", 2.0)):
    lidar = bpy.data.objects.new(name, None)
    lidar.location = (0.0, y, 0.0)
    scene.collection.objects.link(lidar)
    s = lidar.rls_lidar
    s.is_lidar, s.preset_id = True, "livox_mid40"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def names_blend(tmp_path_factory):
    d = tmp_path_factory.mktemp("names")
    blend = d / "names.blend"
    proc = subprocess.run([sys.executable, "-c", BUILD, str(ROOT), str(blend)],
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return blend


def test_lidars_whose_names_give_the_same_files_are_refused(names_blend, tmp_path):
    out = tmp_path / "scan"
    proc = rls("scan", names_blend, "--frames", "1-2", "--out", out)
    line = one_line_error(proc)
    assert "Лидар 1" in line and "Радар 1" in line, line
    assert not out.exists() or not list(out.iterdir())
    # one of them alone is scanned
    alone = rls("scan", names_blend, "--frames", "1", "--out", out, "--sensor", "Лидар 1")
    assert alone.returncode == 0, alone.stderr


def test_a_template_without_frame_over_several_frames_is_refused(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    proc = rls("scan", blend, "--frames", "1-3", "--out", out, "--template", "{sensor}")
    line = one_line_error(proc)
    assert "{frame}" in line and "LiDAR.pcd" in line, line
    assert not out.exists() or not list(out.iterdir())
    one = rls("scan", blend, "--frames", "2", "--out", out, "--template", "{sensor}")
    assert one.returncode == 0, one.stderr  # one frame: no frame number needed


def test_existing_files_are_found_before_the_first_scan(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    assert rls("scan", blend, "--frames", "3", "--out", out).returncode == 0
    before = sorted(p.name for p in out.iterdir())
    proc = rls("scan", blend, "--frames", "1-3", "--out", out, "--workers", "1")
    line = one_line_error(proc)  # no progress line: nothing was scanned
    assert "intersection_LiDAR_000003" in line and "--overwrite" in line, line
    assert sorted(p.name for p in out.iterdir()) == before
