"""Batch runs: ``rls scan --resume``, Ctrl-C, and the ``blender -P`` entry script
(tools/rls_entry.py, run here with the bpy module's Python)."""

import json
import os
import signal
import subprocess
import sys
import tomllib

import pytest

from .conftest import ROOT, one_line_error, rls

ENTRY = ROOT / "tools" / "rls_entry.py"


def summary(proc):
    return json.loads(proc.stdout)


def test_resume_skips_valid_outputs_and_redoes_broken_ones(demo_run, tmp_path):
    demo_out, _, _ = demo_run
    blend = demo_out / "intersection.blend"
    out = tmp_path / "scan"
    first = rls("scan", blend, "--frames", "1-3", "--out", out)
    assert first.returncode == 0, first.stderr
    (out / "intersection_LiDAR_000002.json").unlink()                      # no sidecar
    cloud3 = out / "intersection_LiDAR_000003.pcd"
    cloud3.write_bytes(cloud3.read_bytes()[:300])                    # truncated cloud
    again = rls("scan", blend, "--frames", "1-4", "--out", out, "--resume")
    assert again.returncode == 0, again.stderr
    s = summary(again)
    assert (s["resumed"], s["scanned"]) == (1, 3)
    assert [o.get("resumed", False) for o in s["outputs"]] == [True, False, False, False]
    assert "kept" in again.stderr and "from an earlier run" in again.stderr
    from rls_addon.core.output.io import read_cloud, read_sidecar

    for f in range(1, 5):
        path = out / f"intersection_LiDAR_{f:06d}.pcd"
        assert len(read_cloud(path)) == read_sidecar(path)["points"]
    third = rls("scan", blend, "--frames", "1-4", "--out", out, "--resume")
    assert (summary(third)["resumed"], summary(third)["scanned"]) == (4, 0)
    # a mismatching sidecar (another sensor's or frame's) is not trusted
    side = out / "intersection_LiDAR_000004.json"
    info = json.loads(side.read_text())
    side.write_text(json.dumps(dict(info, points=info["points"] + 1)))
    fourth = rls("scan", blend, "--frames", "1-4", "--out", out, "--resume")
    assert (summary(fourth)["resumed"], summary(fourth)["scanned"]) == (3, 1)
    # without --resume (or --overwrite) existing files still stop the run
    assert "already exists" in one_line_error(rls("scan", blend, "--frames", "1", "--out", out))


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_stops_cleanly(demo_run, tmp_path, workers):
    """Ctrl-C in one process, and with a local cluster of two workers."""
    demo_out, _, _ = demo_run
    out = tmp_path / "scan"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "rls_addon", "scan", str(demo_out / "intersection.blend"),
                             "--frames", "1-60", "--out", str(out), "--workers", workers],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        if workers != "1":
            assert proc.stderr.readline().startswith("rls: ")  # pieces handed out
        for _ in range(2):  # let two frames (pieces) finish, then interrupt mid-run
            assert proc.stderr.readline().startswith("[")
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("[")]
    assert len(lines) == 1 and lines[0].startswith("rls: interrupted after "), stderr
    assert "--resume" in lines[0]
    assert stdout == ""  # no summary for an unfinished run
    names = sorted(os.listdir(out))
    assert not [n for n in names if n.startswith(".") or n.endswith(".tmp")], names
    clouds = [n for n in names if n.endswith(".pcd")]
    assert 2 <= len(clouds) < 60
    assert sorted(n.replace(".pcd", ".json") for n in clouds) == sorted(n for n in names if n.endswith(".json"))
    from rls_addon.core.output.io import read_cloud, read_sidecar

    for n in clouds:
        assert len(read_cloud(out / n)) == read_sidecar(out / n)["points"]


def entry(*args, cwd):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, str(ENTRY), *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_entry_script_runs_the_cli_from_the_source_tree(tmp_path):
    listed = entry("--", "presets", "list", cwd=tmp_path)  # not the repo: found via the script
    assert listed.returncode == 0, listed.stderr
    assert "generic_uniform32" in listed.stdout
    # Blender puts its own options before '--'; only what follows reaches rls
    shown = entry("-b", "scene.blend", "--python-exit-code", "1", "--", "presets", "show",
                  "velodyne_vlp16", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    failed = entry("--", "scan", tmp_path / "missing.blend", "--out", tmp_path / "o", cwd=tmp_path)
    assert failed.returncode == 1
    assert "scene file not found" in one_line_error(failed)
    assert entry("--", "--version", cwd=tmp_path).stdout.startswith("rls ")


def test_entry_script_prefers_the_installed_extension(tmp_path):
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    # make build writes one zip per platform; this machine's is the Linux x64 one.
    zip_path = ROOT / "dist" / f"rls_addon-{manifest['version']}-linux_x64.zip"
    if not zip_path.exists():
        pytest.fail(f"{zip_path} is missing: run 'make build' (make test does)")
    script = (
        "import bpy, runpy, sys\n"
        f"assert bpy.ops.extensions.package_install_files(filepath={str(zip_path)!r}, "
        "repo='user_default', enable_on_install=True) == {'FINISHED'}\n"
        f"ns = runpy.run_path({str(ENTRY)!r})\n"
        "pkg, where = ns['load_rls']()\n"
        "print('FROM', pkg.__name__)\n"
        "sys.exit(ns['main'](['x', '--', 'presets', 'list']))\n")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    env.pop("PYTHONPATH", None)
    proc = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "FROM bl_ext.user_default.rls_addon" in proc.stdout
    assert "generic_uniform32" in proc.stdout
