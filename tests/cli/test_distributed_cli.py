"""Runs spread over Dask workers (a LocalCluster of 2 worker processes on the loopback
address): the same bytes and tables as one process, a killed worker loses nothing,
--resume finishes a killed run, a scene a worker cannot open ends the run with one
line."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, build_blend, rls
from tests.core.external_tools import require_module


@pytest.fixture(autouse=True, scope="module")
def _distributed():
    require_module("distributed", "distributed==2026.8.0")

BUILD = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes import build_scene
from rls_addon.blender.scenes.build import lidar_object, mount_position
build_scene("intersection", bpy.context.scene)
scene = bpy.context.scene
def lidar(name, preset, **kw):
    return lidar_object(scene, name, preset, seed=7, **kw)
pos = mount_position(bpy.data.objects["TL NE"])
lidar("Pole", "hesai_pandar64", location=pos, rotation=(0, math.radians(10), math.radians(-135)))
# a LiDAR on the roof of a car driving 17 m/s through the junction
lidar("Roof", "velodyne_vlp16", parent=bpy.data.objects["Car west"], location=(0, 0, 2.0))
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return build_blend(tmp_path_factory.mktemp("dask"), "junction.blend", BUILD)


@pytest.fixture(scope="module")
def serial(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    proc = rls("scan", scene, "--frames", "1-16", "--out", out, "--workers", "1")
    assert proc.returncode == 0, proc.stderr
    return out, json.loads(proc.stdout)


def clouds(folder):
    return {p.name: p.read_bytes() for p in sorted(Path(folder).glob("*.pcd"))}


def sidecars(folder):
    return {p.name: p.read_bytes() for p in sorted(Path(folder).glob("*.json"))}


def no_leftovers(folder):
    names = [p.name for p in Path(folder).rglob("*")]
    assert not [n for n in names if n.startswith(".") or n.endswith(".tmp")], names
    pcd = {n[:-4] for n in names if n.endswith(".pcd")}
    side = {n[:-5] for n in names if n.endswith(".json") and "instances" not in n}
    assert pcd == side  # every cloud has its sidecar, every sidecar its cloud


def test_sharded_scan_writes_the_bytes_of_a_serial_run(scene, serial, tmp_path,
                                                      tmp_path_factory):
    out, summary = serial
    temp = tmp_path_factory.mktemp("tmpdir")  # the run's temporary directory
    proc = rls("scan", scene, "--frames", "1-16", "--out", tmp_path, "--workers", "2",
               env={"TMPDIR": str(temp)})
    assert proc.returncode == 0, proc.stderr
    # Blender's session folders, the workers' too (a nanny ends its worker without
    # Blender's own clean-up): none left behind
    left = [p.name for p in temp.iterdir() if p.name.startswith(("blender_", "rls-workers-"))]
    assert not left, left
    assert "Dask worker(s) (local cluster)" in proc.stderr and "left" in proc.stderr
    got = json.loads(proc.stdout)
    want = clouds(out)
    assert len(want) == 32 and clouds(tmp_path) == want  # byte for byte, moving LiDAR too
    # the sidecars too (issue 31: they said whether a worker had reused a static cast)
    assert len(sidecars(out)) == 33 and sidecars(tmp_path) == sidecars(out)
    assert [(o["sensor"], o["frame"], o["points"]) for o in got["outputs"]] == \
        [(o["sensor"], o["frame"], o["points"]) for o in summary["outputs"]]
    assert json.loads((tmp_path / "intersection_instances.json").read_text())["instances"] == \
        json.loads((out / "intersection_instances.json").read_text())["instances"]
    no_leftovers(tmp_path)


def _study_tables(folder):
    rows = list(csv.DictReader(open(folder / "candidates.csv")))
    for r in rows:
        r.pop("scan_seconds")
    return rows, (folder / "placements.csv").read_text()


def test_sharded_study_gives_the_tables_of_a_serial_study(scene, tmp_path):
    args = ["study", scene, "--k", "1,2", "--pitch", "0,10,20", "--mount", "TL NE",
            "--mount", "TL SW", "--mount", "TL NW", "--traffic", "25-30:5"]
    one = rls(*args, "--out", tmp_path / "one", "--workers", "1")
    two = rls(*args, "--out", tmp_path / "two", "--workers", "2")
    assert one.returncode == 0 and two.returncode == 0, two.stderr
    assert "candidate blocks on 2 Dask worker(s)" in two.stderr
    assert _study_tables(tmp_path / "one") == _study_tables(tmp_path / "two")


@pytest.fixture
def cluster(tmp_path_factory):
    """A LocalCluster of 2 worker processes (with nannies that restart a killed one),
    their temporary directory one of the test's (Blender's session folders of workers
    that are killed stay there)."""
    from distributed import Client, LocalCluster

    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                     dashboard_address=None, silence_logs=50,
                     env={"PYTHONPATH": str(ROOT), "RLS_THREADS": "1",
                          "TMPDIR": str(tmp_path_factory.mktemp("workers-tmp"))})
    client = Client(c)
    yield c, client
    client.close()
    c.close()


def test_a_killed_worker_loses_nothing(scene, serial, tmp_path, cluster):
    c, client = cluster
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "rls_addon", "scan", str(scene), "--frames",
                             "1-16", "--out", str(tmp_path), "--scheduler", c.scheduler_address],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stderr.readline().startswith("rls: ")  # pieces handed out
        assert proc.stderr.readline().startswith("[")        # a first piece is back
        pids = client.run(os.getpid)
        os.kill(next(iter(pids.values())), signal.SIGKILL)   # one worker dies mid-run
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert clouds(tmp_path) == clouds(serial[0])
    assert json.loads(stdout)["scanned"] + json.loads(stdout)["resumed"] == 32
    no_leftovers(tmp_path)


def test_resume_finishes_a_killed_run(scene, serial, tmp_path, tmp_path_factory):
    # the run's temporary directory one of the test's: a run killed outright cannot
    # remove its workers' (nor Blender its own session folder)
    env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(tmp_path_factory.mktemp("tmpdir")))
    proc = subprocess.Popen([sys.executable, "-m", "rls_addon", "scan", str(scene), "--frames",
                             "1-16", "--out", str(tmp_path), "--workers", "2"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        proc.stderr.readline()
        proc.stderr.readline()  # a first piece is done
        os.killpg(proc.pid, signal.SIGKILL)  # the whole run, workers and all
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    time.sleep(0.5)
    done_before = len(list(tmp_path.glob("*.json")))
    assert 0 < done_before < 32
    again = rls("scan", scene, "--frames", "1-16", "--out", tmp_path, "--workers", "2",
                "--resume")
    assert again.returncode == 0, again.stderr
    s = json.loads(again.stdout)
    assert s["resumed"] > 0 and s["resumed"] + s["scanned"] == 32
    assert clouds(tmp_path) == clouds(serial[0])
    no_leftovers(tmp_path)


def test_a_scene_a_worker_cannot_open_ends_the_run_with_one_line(scene, tmp_path,
                                                                tmp_path_factory):
    """Workers that cannot open the scene (here: a preload makes opening fail, as a
    scene missing from a worker's file system does) end the run at once."""
    from distributed import LocalCluster

    preload = tmp_path / "fail_open.py"
    preload.write_text(
        "def dask_setup(worker):\n"
        "    import rls_addon.commands.worker as w\n"
        "    from rls_addon.core.errors import InputError\n"
        "    def refuse(blend, prepare_blender):\n"
        "        raise InputError(f'scene file not found on this worker: {blend}')\n"
        "    w._open = refuse\n")
    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                     dashboard_address=None, silence_logs=50, preload=[str(preload)],
                     env={"PYTHONPATH": str(ROOT),
                          "TMPDIR": str(tmp_path_factory.mktemp("workers-tmp"))})
    try:
        proc = rls("scan", scene, "--frames", "1-8", "--out", tmp_path / "o", "--scheduler",
                   c.scheduler_address, timeout=120)
        assert proc.returncode == 1
        errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("rls: error")]
        assert len(errors) == 1 and "scene file not found on this worker" in errors[0], proc.stderr
        assert "Traceback" not in proc.stderr
    finally:
        c.close()
