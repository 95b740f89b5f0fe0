"""Issue 41 on the command line: a script that adds the toy device family and output
format of tests/toy_extensions.py through the registries, then runs ``rls`` as
``python -m rls_addon`` does (a team's own launcher), scans a LiDAR whose device is a
toy-family user preset with ``--format toy_text``."""

import json
import os
import subprocess
import sys

import numpy as np

from tests import toy_extensions as toy

from .conftest import ROOT, SCENE_SCRIPT_HEAD, build_blend

SCENE = SCENE_SCRIPT_HEAD + r"""
box("Ground", (-20, -20, -1), (20, 20, 0), label="road")
lidar = bpy.data.objects.new("LiDAR", None)
lidar.location = (0.0, 0.0, 2.0)
bpy.context.scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id, s.noise, s.dropout, s.show_fov = True, "toy_fan_64", False, False, False
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""

LAUNCHER = r"""
import sys
sys.path.insert(0, sys.argv[1])
from tests import toy_extensions as toy
from rls_addon import ensure_registered
from rls_addon.cli import main
with toy.registered():
    code = main(sys.argv[2:], prepare_blender=ensure_registered)
sys.exit(code)
"""


def test_rls_scan_writes_the_toy_format_with_the_toy_device(tmp_path):
    blend = build_blend(tmp_path, "toy.blend", SCENE)
    user = tmp_path / "user"
    toy.write_preset(user)
    out = tmp_path / "out"
    env = dict(os.environ, RLS_USER_PRESET_DIR=str(user))
    proc = subprocess.run([sys.executable, "-c", LAUNCHER, str(ROOT), "scan", str(blend),
                           "--frames", "1", "--format", toy.FORMAT_ID, "--out", str(out),
                           "--workers", "1"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout)["scanned"] == 1
    cloud = out / "Scene_LiDAR_000001.toy"
    blob = cloud.read_bytes()
    assert toy.recognise(blob)
    rec = toy.decode(blob)
    side = json.loads(cloud.with_suffix(".json").read_text())
    assert side["format"] == toy.FORMAT_ID and side["points"] == len(rec) == 64
    assert side["device"]["id"] == "toy_fan_64"
    # the fan at -30 degrees from 2 m over the ground meets it at 4 m
    rng = np.sqrt(rec["x"] ** 2 + rec["y"] ** 2 + rec["z"] ** 2)
    assert np.abs(rng - 4.0).max() < 1e-4
