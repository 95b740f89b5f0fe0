"""SUMO networks for the tests, made with the installed wheel's netgenerate and
netconvert (called by path, SUMO_HOME set in the child's environment)."""

import os
import subprocess
from pathlib import Path

from tests.core.external_tools import require_module

FIXTURES = Path(__file__).resolve().parent / "fixtures"
OSM_FIXTURE = FIXTURES / "osm" / "crossing.osm"

# SUMO's FCD of one car driving 10 m north past the grid's middle crossing in 1 s (as
# ``sumo --fcd-output`` writes it, without its comment).
ONE_CAR_FCD = """<?xml version="1.0" encoding="UTF-8"?>
<fcd-export>
    <timestep time="0.00">
        <vehicle id="a" x="60.00" y="70.00" angle="0.00" type="DEFAULT_VEHTYPE" speed="10" pos="5" lane="e_0" slope="0.00"/>
    </timestep>
    <timestep time="1.00">
        <vehicle id="a" x="60.00" y="80.00" angle="0.00" type="DEFAULT_VEHTYPE" speed="10" pos="15" lane="e_0" slope="0.00"/>
    </timestep>
</fcd-export>
"""

# A 3 x 3 grid: its middle junction is a four-way crossing, with sidewalks and crossings.
GRID_OPTIONS = ("--grid", "--grid.number", "3", "--grid.length", "80",
                "--sidewalks.guess", "--crossings.guess")
# docs/roads.md's command for an OpenStreetMap extract (the defaults it pins included).
OSM_OPTIONS = ("--osm.sidewalks", "--osm.crossings", "--sidewalks.guess", "--crossings.guess",
               "--junctions.corner-detail", "5", "--default.sidewalk-width", "2",
               "--default.crossing-width", "4")


def sumo_home():
    sumo = require_module("sumo", "eclipse-sumo==1.28.0")
    return sumo.SUMO_HOME


def run_sumo_binary(name, *args):
    home = sumo_home()
    env = dict(os.environ, SUMO_HOME=home)
    proc = subprocess.run([os.path.join(home, "bin", name), *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def grid_net(folder, *extra):
    out = Path(folder) / "grid.net.xml"
    run_sumo_binary("netgenerate", *GRID_OPTIONS, *extra, "-o", out)
    return out


def osm_net(folder):
    out = Path(folder) / "crossing.net.xml"
    run_sumo_binary("netconvert", "--osm-files", OSM_FIXTURE, *OSM_OPTIONS, "-o", out)
    return out
