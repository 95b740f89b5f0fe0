"""Every command in README.md's shell blocks runs as it stands, in the order it stands,
from a fresh checkout's top folder: a command added to the README is run here without
anyone listing it (only the ``make`` lines are left to their own targets, named below).

The commands run through the shell in a folder that holds the checkout's files as
links (``.venv``, ``rls_addon``, ``tools``, ...) and an empty ``sample_scenes`` beside
``make_scenes.py``, so the scenes are made fresh and nothing is written into the
checkout. ``blender`` is ``blender_standin.py`` (this machine runs Blender as the
``bpy`` module): it opens the file and hands the arguments to the handler the enabled
extension registers for ``-c rls``, as Blender does.
"""

import os
import re
import shlex
import subprocess
import sys

import pytest

from .conftest import ROOT

# Lines that are not commands on a scene, and where they are tested instead.
NOT_RUN_HERE = {
    "make demo": "tests/cli/test_demo_and_scan_cli.py runs rls demo",
    "make test": "the whole suite with Debian packages installed: the integrator's run",
}


def readme_commands(text):
    """The commands of ``text``'s ```sh blocks, continuation lines joined, comments
    and blank lines dropped."""
    out = []
    for block in re.findall(r"^[ \t]*```sh\n(.*?)^[ \t]*```", text, re.M | re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            words = shlex.split(line, comments=True)
            if words:
                out.append(shlex.join(words))
    return out


def test_readme_commands_are_found():
    cmds = readme_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    assert "make demo" in cmds
    assert any(c.startswith(".venv/bin/python -m rls_addon scan") for c in cmds), cmds
    assert any(c.startswith("blender -b") for c in cmds), cmds
    assert readme_commands("```sh\na \\\n  b  # c\n# d\n```\n") == ["a b"]


def sandbox(folder):
    """``folder`` as a fresh checkout: links to the checkout's files, an empty
    ``sample_scenes`` with its script, ``bin/blender`` the stand-in."""
    for entry in os.listdir(ROOT):
        if entry in ("sample_scenes", "out", "build", "dist") or entry.startswith(".git"):
            continue
        os.symlink(ROOT / entry, folder / entry)
    (folder / "sample_scenes").mkdir()
    os.symlink(ROOT / "sample_scenes" / "make_scenes.py", folder / "sample_scenes" / "make_scenes.py")
    bin_dir = folder / "bin"
    bin_dir.mkdir()
    blender = bin_dir / "blender"
    blender.write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)} "
                       f"{shlex.quote(str(ROOT / 'tests' / 'cli' / 'blender_standin.py'))} \"$@\"\n")
    blender.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "RLS_THREADS")}
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    return env


@pytest.mark.slow  # about 20 s here: a scene made, 20 frames of one LiDAR, then of two
def test_every_readme_command_runs_verbatim(tmp_path):
    cmds = readme_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    env = sandbox(tmp_path)
    ran = []
    for cmd in cmds:
        if cmd in NOT_RUN_HERE:
            continue
        proc = subprocess.run(cmd, shell=True, cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=900)
        assert proc.returncode == 0, f"{cmd}\n{proc.stderr[-3000:]}"
        ran.append((cmd, proc))
    assert len(ran) >= 5, [c for c, _ in ran]
    # what the README's lines say they do, done: the sample LiDAR's 20 frames, then 20 of
    # the sample LiDAR and the one added
    out = tmp_path / "out"
    assert len(list((out / "scan").glob("intersection_LiDAR_*.pcd"))) == 20
    two = sorted(p.name for p in (out / "scan_two").glob("*.pcd"))
    assert len(two) == 40 and sum("North" in n for n in two) == 20, two
    listing = next(p.stdout for c, p in ran if " lidar list " in c)
    assert "LiDAR" in listing and "Hesai Pandar64" in listing
