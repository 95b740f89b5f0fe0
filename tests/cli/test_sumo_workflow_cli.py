"""A real junction with real traffic, as docs/roads.md and docs/traffic.md tell a user
to make it: a SUMO network -> `rls scene from-net` (the junction at the scene's origin)
-> `rls traffic generate` -> `rls traffic import` (taking the scene's origin) ->
`rls study --traffic`. The traffic lands on the roads: vehicles are scored in the
junction's region."""

import json

import pytest

from ..sumo_nets import grid_net
from .conftest import one_line_error, rls

pytestmark = pytest.mark.slow


def test_net_to_scene_to_traffic_to_study(tmp_path):
    net = grid_net(tmp_path)
    roads = tmp_path / "roads.blend"
    built = rls("scene", "from-net", net, "--origin", "junction", "--out", roads)
    assert built.returncode == 0, built.stderr
    origin = json.loads(built.stdout)["origin"]
    assert origin != [0.0, 0.0]  # the junction, not the network's corner
    fcd = tmp_path / "traffic.xml"
    gen = rls("traffic", "generate", net, "--duration", "40", "--rate", "3000", "--seed", "5",
              "--out", fcd)
    assert gen.returncode == 0, gen.stderr
    scene = tmp_path / "busy.blend"
    imp = rls("traffic", "import", roads, "--fcd", fcd, "--begin", "20", "--end", "30",
              "--out", scene)
    assert imp.returncode == 0, imp.stderr
    # another origin than the scene's would put the traffic beside its roads: refused
    bad = rls("traffic", "import", roads, "--fcd", fcd, "--origin", "0", "0",
              "--out", tmp_path / "off.blend")
    assert "would miss its roads" in one_line_error(bad)
    assert not (tmp_path / "off.blend").exists()
    out = tmp_path / "study"
    study = rls("study", scene, "--traffic", "1-81:20", "--out", out)
    assert study.returncode == 0, study.stderr
    vis = json.loads((out / "study.json").read_text())["visibility"]
    assert vis["vehicle_frames"] >= 5, vis  # SUMO's vehicles cross the junction's region
