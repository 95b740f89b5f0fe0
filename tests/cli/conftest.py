"""Command-line tier: run ``python -m rls_addon`` as a user does, in a subprocess."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# The start of the scripts that build test scenes in a subprocess (argv[1]: the
# repository): Blender's factory settings, empty, with RLS registered.
SCENE_SCRIPT_HEAD = r"""
import sys, math, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
rls_addon.register()
bpy.ops.wm.read_factory_settings(use_empty=True)
if not hasattr(bpy.types.Object, "rls_lidar"):
    rls_addon.register()

def box(name, lo, hi, reflectivity=None, label=None):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
         (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    me = bpy.data.meshes.new(name)
    me.from_pydata(v, [], f)
    if reflectivity is not None:
        mat = bpy.data.materials.new(name)
        mat["rls_reflectivity"] = reflectivity
        me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    if label is not None:
        ob["rls_label"] = label
    bpy.context.scene.collection.objects.link(ob)
    return ob
"""


def build_blend(folder, name, script, *extra):
    """Run a scene-building ``script`` (``SCENE_SCRIPT_HEAD`` + its own lines) in a
    subprocess with argv = [repository, FOLDER/NAME, *extra]; return the .blend path."""
    blend = Path(folder) / name
    proc = subprocess.run([sys.executable, "-c", script, str(ROOT), str(blend),
                           *map(str, extra)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return blend


def rls(*args, cwd=None, timeout=600, env=None):
    """Run ``python -m rls_addon ARGS`` (``env``: variables set beside ours); return the
    CompletedProcess (text mode)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), **(env or {}))
    return subprocess.run([sys.executable, "-m", "rls_addon", *map(str, args)], cwd=cwd or ROOT,
                          env=env, capture_output=True, text=True, timeout=timeout)


def assert_complete(case, out):
    """What a stopped run of ``case`` (a name that starts with its command: scan,
    dataset, or else a study) may leave in ``out``: complete files only, no temporary."""
    if not out.exists():
        return
    names = [p.name for p in out.rglob("*")]
    assert not [n for n in names if n.startswith(".") or n.endswith(".tmp")], (case, names)
    if case.startswith("scan"):
        from rls_addon.core.output.io import read_cloud, read_sidecar

        clouds = sorted(out.glob("*.pcd"))
        sides = {p.stem for p in out.glob("*.json") if "_instances" not in p.name}
        assert {p.stem for p in clouds} == sides, case  # a cloud has its sidecar
        for p in clouds:
            assert len(read_cloud(p)) == read_sidecar(p)["points"], (case, p)
    elif case.startswith("dataset"):
        import numpy as np

        for meta in out.rglob("meta/*.json"):  # a frame's meta is written last
            body = json.loads(meta.read_text())
            root = meta.parent.parent
            npy = root / "points" / f"{meta.stem}.npy"
            pts = np.load(npy) if npy.is_file() else \
                np.fromfile(root / "points" / f"{meta.stem}.bin", np.float32).reshape(-1, 4)
            assert len(pts) == body["points"], (case, meta)
            if root.name != "background":  # background sweeps have no labels
                assert (root / "labels" / f"{meta.stem}.txt").is_file(), (case, meta)
    else:  # a study's report is one set: all of it or none of it
        report = {n for n in os.listdir(out)}
        assert not report or {"study.json", "candidates.csv", "placements.csv"} <= report, report


def progress_line(line):
    """True for what a run says as it goes rather than its outcome: a scan's frame
    lines ("[1/2] ..."), the throttled progress and status lines of the commands that
    report as they work ("rls: scene: ...", "rls: traffic: ...": they start after a
    quiet second, so a busy machine shows more of them) and notices."""
    return line.startswith(("[", "rls: scene: ", "rls: traffic: ", "rls: notice: "))


def outcome_lines(stderr):
    """The lines of ``stderr`` that are not progress (``progress_line``) nor blank."""
    return [ln for ln in stderr.splitlines() if ln.strip() and not progress_line(ln)]


def one_line_error(proc):
    """Assert a failed run printed exactly one error line on stderr (besides progress,
    which a busy machine may show before a late refusal); return it."""
    assert proc.returncode != 0, proc.stdout
    lines = outcome_lines(proc.stderr)
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("rls: error: "), lines[0]
    return lines[0]


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    proc = rls("demo", "--out", out)
    assert proc.returncode == 0, proc.stderr
    start = proc.stdout.index("{")
    summary, _ = json.JSONDecoder().raw_decode(proc.stdout[start:])
    return out, summary, proc
