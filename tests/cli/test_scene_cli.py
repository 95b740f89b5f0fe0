"""``rls scene from-net`` as users run it: a netgenerate crossing and the hand-written
OSM extract made into scenes, one-line errors, and ``rls study --traffic`` on a
written scene."""

import csv
import json
import os
import subprocess
import sys

import pytest

from tests.sumo_nets import grid_net, osm_net

from .conftest import ROOT, one_line_error, rls


@pytest.fixture(scope="module")
def nets(tmp_path_factory):
    folder = tmp_path_factory.mktemp("nets")
    return {"grid": grid_net(folder), "osm": osm_net(folder)}


@pytest.mark.parametrize("which", ["grid", "osm"])
def test_from_net_writes_a_scene(nets, tmp_path, which):
    net = nets[which]
    before = net.read_bytes()
    out = tmp_path / "scene.blend"
    proc = rls("scene", "from-net", net, "--out", out)
    assert proc.returncode == 0, proc.stderr
    s = json.loads(proc.stdout)
    assert out.is_file() and net.read_bytes() == before
    assert s["objects"] == ["Crossings", "Kerbs", "Road", "Sidewalk"]
    assert len(s["mounts"]) >= 3 and s["infralob"] == "InfraLOB"
    assert s["origin"] == [0.0, 0.0]
    assert "triangulating" in proc.stderr
    assert [p for p in os.listdir(tmp_path) if p != "scene.blend"] == []
    if which == "grid":
        assert s["junction"] == "B1"
    again = rls("scene", "from-net", net, "--out", out)
    assert "already exists" in one_line_error(again)
    assert rls("scene", "from-net", net, "--out", out, "--overwrite", "--origin",
               "junction").returncode == 0


def test_from_net_errors_are_one_line(nets, tmp_path):
    out = tmp_path / "s.blend"
    err = one_line_error(rls("scene", "from-net", nets["grid"], "--out", out, "--junction", "Z9"))
    assert "no junction 'Z9'" in err and "B1" in err
    bad = tmp_path / "bad.net.xml"
    bad.write_text("<net><edge id='a'")
    assert "not a well-formed SUMO network" in one_line_error(
        rls("scene", "from-net", bad, "--out", out))
    cut = tmp_path / "cut.net.xml"
    text = nets["grid"].read_text()
    cut.write_text(text[: len(text) // 3])
    assert "truncated" in one_line_error(rls("scene", "from-net", cut, "--out", out))
    empty = tmp_path / "empty.net.xml"
    empty.write_text('<?xml version="1.0"?>\n<net version="1.20">\n'
                     '<location netOffset="0.00,0.00" convBoundary="0,0,1,1" '
                     'origBoundary="0,0,1,1" projParameter="!"/>\n</net>\n')
    assert "has no junctions" in one_line_error(rls("scene", "from-net", empty, "--out", out))
    assert "not found" in one_line_error(rls("scene", "from-net", tmp_path / "no.net.xml",
                                             "--out", out))
    assert not out.exists()


def test_from_net_without_sumolib(nets, tmp_path):
    fake = tmp_path / "fake"
    (fake / "sumolib").mkdir(parents=True)
    (fake / "sumolib" / "__init__.py").write_text("raise ImportError('sumolib hidden for a test')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(fake), str(ROOT)]))
    proc = subprocess.run([sys.executable, "-m", "rls_addon", "scene", "from-net", str(nets["grid"]),
                           "--out", str(tmp_path / "s.blend")], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert "pip install sumolib" in one_line_error(proc)


# A car driving east through the middle junction of the grid (on its eastbound lane,
# 1.6 m south of the road's middle) while the study scores the traffic.
CAR = r"""
import sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
if not hasattr(bpy.types.Object, "rls_lidar"):
    rls_addon.register()
from rls_addon.blender.scenes.build import car, collection, standard_materials
scene = bpy.context.scene
ox, oy = scene["rls_sumo_origin"]
y = 80.0 - 1.6 - oy
car(collection(scene, "Vehicles"), "Car", standard_materials()["paint"],
    [(60.0 - ox, y), (100.0 - ox, y)], [1, 21])
scene.frame_start, scene.frame_end = 1, 21
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
"""


@pytest.mark.slow
def test_study_with_traffic_runs_on_a_written_scene(nets, tmp_path):
    roads = tmp_path / "roads.blend"
    assert rls("scene", "from-net", nets["grid"], "--out", roads).returncode == 0
    blend = tmp_path / "with_car.blend"
    proc = subprocess.run([sys.executable, "-c", CAR, str(ROOT), str(roads), str(blend)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = tmp_path / "study"
    proc = rls("study", blend, "--pitch", "15", "--traffic", "8-12:2", "--out", out)
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(out / "candidates.csv")))
    assert sorted(r["name"] for r in rows) == ["Pole NE B1", "Pole NW B1", "Pole SE B1",
                                               "Pole SW B1"]
    assert all(float(r["infra_d"]) > 0 for r in rows)
    report = json.loads((out / "study.json").read_text())
    assert report["visibility"]["frames"] == [8, 10, 12]
    assert max(float(r["share_5"]) for r in rows) > 0  # the car is seen in the region
