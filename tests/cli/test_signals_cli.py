"""SIGTERM and SIGHUP (kill, SLURM, Kubernetes, systemd) stop a run as Ctrl-C does, and
the temporaries a SIGKILL leaves are removed by the next --resume or --overwrite run."""

import hashlib
import os
import signal
import subprocess
import sys

import pytest

from .conftest import ROOT, rls


def start_scan(blend, out, frames="1-60"):  # the traffic is keyed over 1-60
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "rls_addon", "scan", str(blend), "--frames",
                             frames, "--out", str(out), "--workers", "1"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def complete_clouds(out):
    """Only complete clouds, each with its sidecar, and no temporary file."""
    from rls_addon.core.output.io import read_cloud, read_sidecar

    names = sorted(os.listdir(out))
    assert not [n for n in names if n.startswith(".") or n.endswith(".tmp")], names
    clouds = [n for n in names if n.endswith(".pcd")]
    assert sorted(n[:-4] + ".json" for n in clouds) == \
        sorted(n for n in names if n.endswith(".json") and "_instances" not in n)
    for n in clouds:
        assert len(read_cloud(out / n)) == read_sidecar(out / n)["points"]
    return clouds


@pytest.mark.parametrize("sig,code,after", [(signal.SIGTERM, 143, 0), (signal.SIGTERM, 143, 1),
                                            (signal.SIGTERM, 143, 3), (signal.SIGHUP, 129, 2)])
def test_sigterm_and_sighup_stop_like_ctrl_c(demo_run, tmp_path, sig, code, after):
    demo_out, _, _ = demo_run
    out = tmp_path / "scan"
    proc = start_scan(demo_out / "intersection.blend", out)
    try:
        for _ in range(after):  # let some scans finish, then stop mid-run
            assert proc.stderr.readline().startswith("[")
        if not after:  # while the scene is opened or the first frame scanned
            import time

            time.sleep(1.5)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("[")]
    assert len(lines) == 1 and lines[0].startswith("rls: interrupted"), stderr
    assert stdout == ""
    if out.exists():
        assert len(complete_clouds(out)) < 60


def digests(folder):
    """Every file's bytes, sidecars included."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir())}


def test_resume_removes_what_a_sigkill_left(demo_run, tmp_path):
    demo_out, _, _ = demo_run
    blend = demo_out / "intersection.blend"
    whole = tmp_path / "whole"
    assert rls("scan", blend, "--frames", "1-3", "--out", whole).returncode == 0
    out = tmp_path / "killed"
    first = rls("scan", blend, "--frames", "1", "--out", out)
    assert first.returncode == 0, first.stderr
    # what a write of frame 2 killed by SIGKILL leaves: a truncated temporary
    from rls_addon.core.output.io.atomic import temporary_name

    cloud2 = whole / "intersection_LiDAR_000002.pcd"
    stale = out / temporary_name("intersection_LiDAR_000002.pcd", "k1ll3d")
    stale.write_bytes(cloud2.read_bytes()[:200])
    again = rls("scan", blend, "--frames", "1-3", "--out", out, "--resume")
    assert again.returncode == 0, again.stderr
    assert not stale.exists()
    complete_clouds(out)
    assert digests(out) == digests(whole)
    # --overwrite cleans its outputs' temporaries too
    stale.write_bytes(b"partial")
    over = rls("scan", blend, "--frames", "1-3", "--out", out, "--overwrite")
    assert over.returncode == 0, over.stderr
    assert not stale.exists()
    assert digests(out) == digests(whole)


def test_a_stopped_dataset_says_what_its_resume_writes(demo_run, tmp_path):
    """A kitti dataset stopped mid-run has its frames' files but not its splits and
    description (written once every scan is done): the one line says so, and a
    --resume over the frames on disk writes them."""
    demo_out, _, _ = demo_run
    blend = demo_out / "intersection.blend"
    out = tmp_path / "dataset"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "rls_addon", "dataset", str(blend),
                             "--layout", "kitti", "--frames", "1-60", "--out", str(out),
                             "--workers", "1"], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        scans = 0
        while scans < 2:  # the background sweeps first, then two of the frames
            line = proc.stderr.readline()
            assert line.startswith("["), line
            scans += line.startswith("[") and not line.startswith("[background]")
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("[")]
    assert len(lines) == 1 and lines[0].startswith("rls: interrupted after "), stderr
    assert lines[0].endswith("rerun with --resume to continue (the splits (ImageSets) and "
                             "dataset.json are written once every scan is done)")
    root = out / "LiDAR"
    written = sorted(p.stem for p in (root / "points").glob("*.npy"))
    assert written and not (root / "ImageSets").exists() and not (root / "dataset.json").exists()
    done = rls("dataset", blend, "--layout", "kitti", "--frames", f"1-{len(written)}",
               "--out", out, "--resume")
    assert done.returncode == 0, done.stderr
    listed = (root / "ImageSets" / "train.txt").read_text().split() + \
        (root / "ImageSets" / "val.txt").read_text().split()
    assert (root / "dataset.json").is_file() and set(listed) <= set(written) and listed
