"""``rls traffic`` as a user runs it: ``generate`` twice with one seed gives the same
bytes (FCD, routes, vTypes) and, imported, the same scans; another seed other traffic;
bad input gets one ``rls: error:`` line and leaves the scene as it was."""

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls
from tests.core.external_tools import require_module


@pytest.fixture(autouse=True, scope="module")
def _sumo():
    require_module("sumo", "eclipse-sumo==1.28.0")


SCENE = SCENE_SCRIPT_HEAD + r"""
sc = bpy.context.scene
sc.render.fps = 10
box("Ground", (-150, -150, -0.1), (150, 150, 0.0), label="road")
lidar = bpy.data.objects.new("LiDAR", None)
lidar.location = (0.0, 0.0, 4.0)
sc.collection.objects.link(lidar)
lidar.rls_lidar.is_lidar = True
lidar.rls_lidar.preset = "generic_uniform32"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


def sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def net(tmp_path_factory):
    from rls_addon.core.traffic.sumo_run import binary, sumo_home

    d = tmp_path_factory.mktemp("net")
    path = d / "cross.net.xml"
    subprocess.run([binary(sumo_home(), "netgenerate"), "--grid", "--grid.number", "3",
                    "--grid.length", "60", "--sidewalks.guess", "true", "-o", str(path)],
                   check=True, capture_output=True)
    return path


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return build_blend(tmp_path_factory.mktemp("scene"), "empty.blend", SCENE)


@pytest.mark.slow
def test_same_seed_same_bytes_and_scans_other_seed_other_traffic(net, scene, tmp_path):
    outs = {}
    for name, seed in (("a", 5), ("b", 5), ("c", 6)):
        fcd = tmp_path / f"{name}.xml"
        proc = rls("traffic", "generate", net, "--duration", "60", "--rate", "1800",
                   "--seed", seed, "--out", fcd)
        assert proc.returncode == 0, proc.stderr
        outs[name] = fcd
    for suffix in (".xml", ".rou.xml", ".vtypes.xml"):
        a, b = (str(outs[n])[:-4] + suffix for n in "ab")
        assert sha(a) == sha(b), suffix
    assert sha(outs["a"]) != sha(outs["c"])
    assert "generated on" not in outs["a"].read_text()
    scans = {}
    for name in ("a", "b"):
        blend = tmp_path / f"{name}.blend"
        proc = rls("traffic", "import", scene, "--fcd", outs[name], "--out", blend,
                   "--origin", "60", "60")
        assert proc.returncode == 0, proc.stderr
        out = tmp_path / f"scan_{name}"
        proc = rls("scan", blend, "--frames", "300", "--out", out, "--seed", "1",
                   "--format", "pcd_binary")
        assert proc.returncode == 0, proc.stderr
        clouds = sorted(out.glob("*.pcd"))
        assert clouds
        scans[name] = [sha(c) for c in clouds]
    # Blender's .blend holds pointers and is not byte-stable: "the same bytes" of an
    # imported scene is the same scan of it
    assert scans["a"] == scans["b"]


def test_import_errors_one_line_scene_unchanged(scene, tmp_path):
    before = sha(scene)
    out = tmp_path / "new.blend"
    bad = tmp_path / "bad.xml"
    bad.write_text("this is not XML")
    line = one_line_error(rls("traffic", "import", scene, "--fcd", bad, "--out", out))
    assert "line 1" in line
    cut = tmp_path / "cut.xml"
    cut.write_text('<fcd-export>\n<timestep time="0">\n<vehicle id="a" x="1" y="2" angle="0" '
                   'type="DEFAULT_VEHTYPE"/>\n')
    line = one_line_error(rls("traffic", "import", scene, "--fcd", cut, "--out", out))
    assert "not complete" in line and "line 4" in line
    unsized = tmp_path / "unsized.xml"
    unsized.write_text('<fcd-export><timestep time="0"><vehicle id="a" x="1" y="2" angle="0" '
                       'type="mystery"/></timestep></fcd-export>')
    line = one_line_error(rls("traffic", "import", scene, "--fcd", unsized, "--out", out))
    assert "'mystery'" in line and "no size" in line
    line = one_line_error(rls("traffic", "import", scene, "--fcd", unsized, "--out", scene))
    assert "never changes" in line
    assert not out.exists() and sha(scene) == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_sumo_missing_says_how_to_install(net, tmp_path):
    fake = tmp_path / "fake"
    (fake / "sumo").mkdir(parents=True)
    (fake / "sumo" / "__init__.py").write_text("raise ImportError('no sumo here')\n")
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if k != "SUMO_HOME"}
    env["PYTHONPATH"] = os.pathsep.join([str(fake), str(root)])
    proc = subprocess.run([sys.executable, "-m", "rls_addon", "traffic", "generate", str(net),
                           "--duration", "10", "--rate", "100", "--seed", "1", "--out",
                           str(tmp_path / "f.xml")], env=env, capture_output=True, text=True,
                          cwd=root)
    line = one_line_error(proc)
    assert "pip install eclipse-sumo sumolib" in line
    assert not (tmp_path / "f.xml").exists()
