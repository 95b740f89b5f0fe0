"""--resume keeps a frame only when its sidecar's settings are the run's; files of
another format beside the run's outputs are reported (and removed where the sidecars
the run replaces described them)."""

import json

import pytest

from .conftest import rls


def summary(proc):
    return json.loads(proc.stdout)


@pytest.mark.parametrize("flag,value,name", [
    ("--seed", "7", "seed"),
    ("--motion", "snapshot", "motion"),
    ("--weather", "fog:visibility=50", "weather"),
    ("--format", "pcd_ascii", "format"),
    ("--fields", "intensity", "fields"),
    ("--frame-space", "world", "frame_space"),
])
def test_resume_rescans_frames_written_with_other_settings(demo_run, tmp_path, flag, value, name):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    first = rls("scan", blend, "--frames", "1-3", "--out", out, "--workers", "1")
    assert first.returncode == 0, first.stderr
    again = rls("scan", blend, "--frames", "1-3", "--out", out, "--resume", flag, value,
                "--workers", "1")
    assert again.returncode == 0, again.stderr
    assert (summary(again)["resumed"], summary(again)["scanned"]) == (0, 3)
    told = [ln for ln in again.stderr.splitlines() if "other settings" in ln]
    assert len(told) == 1 and name in told[0], again.stderr
    for f in range(1, 4):
        info = json.loads((out / f"intersection_LiDAR_{f:06d}.json").read_text())
        assert info["seed"] == (7 if name == "seed" else 0)
    # the same settings again: every frame kept, nothing said
    third = rls("scan", blend, "--frames", "1-3", "--out", out, "--resume", flag, value,
                "--workers", "1")
    assert (summary(third)["resumed"], summary(third)["scanned"]) == (3, 0), third.stderr
    assert "other settings" not in third.stderr


def test_resume_reports_files_of_another_format(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    assert rls("scan", blend, "--frames", "1-2", "--out", out, "--workers", "1").returncode == 0
    again = rls("scan", blend, "--frames", "1-2", "--out", out, "--resume", "--format",
                "ply_binary", "--workers", "1")
    assert again.returncode == 0, again.stderr
    assert summary(again)["scanned"] == 2
    told = [ln for ln in again.stderr.splitlines() if ln.startswith("rls: notice:")
            and "another format" in ln]
    assert len(told) == 1 and "2 " in told[0] and ".pcd" in told[0], again.stderr
    assert "removed once its frame's new files are written" in told[0]
    # the sidecars described them; replaced, they would describe no cloud of theirs
    assert sorted(p.name for p in out.glob("intersection_LiDAR_*")) == [
        f"intersection_LiDAR_{f:06d}.{e}" for f in (1, 2) for e in ("json", "ply")]


def test_resume_over_workers_says_so_too(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "scan"
    assert rls("scan", blend, "--frames", "1-4", "--out", out, "--workers", "1").returncode == 0
    again = rls("scan", blend, "--frames", "1-4", "--out", out, "--resume", "--seed", "7",
                "--workers", "2")
    assert again.returncode == 0, again.stderr
    assert (summary(again)["resumed"], summary(again)["scanned"]) == (0, 4)
    told = [ln for ln in again.stderr.splitlines() if "other settings" in ln]
    assert told and all("seed" in ln for ln in told), again.stderr


@pytest.mark.parametrize("layout,extra", [("kitti", []), ("kitti", ["--level"]),
                                          ("opv2v", [])])
def test_dataset_resume_keeps_only_frames_of_the_same_settings(demo_run, tmp_path, layout,
                                                               extra):
    """Issue 31: rls dataset --resume kept frames made with another seed or layout
    option. Each frame now records its settings (KITTI's meta, OPV2V's YAML)."""
    blend = demo_run[0] / "intersection.blend"
    out = tmp_path / "data"
    args = ["dataset", blend, "--layout", layout, "--frames", "1-2", "--out", out,
            "--workers", "1"]
    assert rls(*args).returncode == 0
    changed = ["--seed", "7"] if not extra else extra
    again = rls(*args, "--resume", *changed)
    assert again.returncode == 0, again.stderr
    assert (summary(again)["resumed"], summary(again)["scanned"]) == (0, 2)
    told = [ln for ln in again.stderr.splitlines() if "other settings" in ln]
    name = "seed" if not extra else "label_frame"
    assert len(told) == 1 and name in told[0], again.stderr
    third = rls(*args, "--resume", *changed)
    assert (summary(third)["resumed"], summary(third)["scanned"]) == (2, 0), third.stderr
