"""Running SUMO: find an install, make random traffic over a network and simulate it
with floating-car-data output (``rls traffic generate``).

SUMO is found, in this order, in the ``eclipse-sumo`` wheel (``import sumo``:
``sumo.SUMO_HOME``) and at the ``SUMO_HOME`` environment variable (a SUMO install with
``bin/sumo`` and ``tools/randomTrips.py``); without either, ``SumoMissing`` says how to
install it. SUMO's own programs are run by path, with SUMO_HOME set for them.

What ``generate`` runs (in a temporary folder; the outputs are written atomically):
1. ``randomTrips.py`` (SUMO's tool, run with this Python) over the network: vehicles
   departing every 3600/rate s from 0 to ``duration`` on edges that allow passenger
   cars, each drawing its type from RLS's vType distribution (``vtypes_xml``: car,
   van, truck, bus, motorcycle, bicycle with SUMO's default sizes but the car's;
   pedestrians 0.21 x 0.48 x 1.72 m, SUMO's rounded to cm), routed
   by duarouter (``--validate``); with pedestrians, a second run of persons walking.
   Both get ``--seed``.
2. ``sumo`` with those routes (duarouter writes the types used into them), ``--seed``, ``--step-length``, ``--end
   duration`` and ``--fcd-output``.
SUMO writes a comment with the date and its options at the top of each file; RLS drops
that first comment, so the same network, options and seed give byte-identical files.
Next to ``OUT.xml`` it writes ``OUT.vtypes.xml`` (the vTypes; ``rls traffic import``
reads it by itself) and ``OUT.rou.xml`` (the routes SUMO ran).
"""

import math
import os
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, fields

from ..errors import InputError, RLSError
from ..output.io.atomic import atomic_write_files
from ..roads.layout import STEP_S
from ..roads.network import refuse_internal_dtd
from .xml_errors import parse_reason


class SumoMissing(RLSError):
    """No SUMO install to run."""


INSTALL_HINT = ("SUMO is not installed: pip install eclipse-sumo sumolib (or set SUMO_HOME "
                "to a SUMO install with bin/sumo and tools/randomTrips.py)")

# RLS's vehicle mix (probabilities) with sizes (m): SUMO's vClass defaults (see
# vtypes.VCLASS_DEFAULTS) but the car, 4.6 m long as a typical European car.
VEHICLE_MIX = (
    ("rls_car", "passenger", 0.70, (4.6, 1.8, 1.5)),
    ("rls_van", "delivery", 0.08, (6.5, 2.16, 2.86)),
    ("rls_truck", "truck", 0.07, (7.1, 2.4, 2.4)),
    ("rls_bus", "bus", 0.03, (12.0, 2.5, 3.4)),
    ("rls_motorcycle", "motorcycle", 0.06, (2.2, 0.9, 1.5)),
    ("rls_bicycle", "bicycle", 0.06, (1.6, 0.65, 1.7)),
)
# duarouter writes the types it routed into its routes with two decimals, and SUMO runs
# those: the sizes here have two decimals so OUT.vtypes.xml says what SUMO ran.
PEDESTRIAN = ("rls_pedestrian", "pedestrian", (0.21, 0.48, 1.72))
DISTRIBUTION = "rls_vehicles"


def sumo_home():
    """The SUMO install to run (see the module doc), or ``SumoMissing``."""
    try:
        import sumo  # the eclipse-sumo wheel

        home = sumo.SUMO_HOME
        if _usable(home):
            return str(home)
    except ImportError:
        pass
    home = os.environ.get("SUMO_HOME")
    if home and _usable(home):
        return home
    raise SumoMissing(INSTALL_HINT)


def _usable(home):
    return bool(home) and os.path.isfile(os.path.join(home, "tools", "randomTrips.py")) \
        and any(os.path.isfile(os.path.join(home, "bin", n)) for n in ("sumo", "sumo.exe"))


def binary(home, name):
    for n in (name, name + ".exe"):
        p = os.path.join(home, "bin", n)
        if os.path.isfile(p):
            return p
    raise SumoMissing(f"{name} is not in {home}/bin: " + INSTALL_HINT)


def sibling(path, suffix):
    """``OUT.xml`` -> ``OUT<suffix>`` (e.g. '.vtypes.xml')."""
    base = path[:-4] if path.lower().endswith(".xml") else path
    return base + suffix


def vtypes_xml():
    lines = ['<additional>', f'    <vTypeDistribution id="{DISTRIBUTION}">']
    for tid, vclass, prob, (length, w, h) in VEHICLE_MIX:
        lines.append(f'        <vType id="{tid}" vClass="{vclass}" length="{length}" width="{w}" '
                     f'height="{h}" probability="{prob}"/>')
    tid, vclass, (length, w, h) = PEDESTRIAN
    lines += ['    </vTypeDistribution>',
              f'    <vType id="{tid}" vClass="{vclass}" length="{length}" width="{w}" '
              f'height="{h}"/>',
              '</additional>', '']
    return "\n".join(lines)


def has_sidewalks(net):
    """Whether the network has lanes only pedestrians may use."""
    refuse_internal_dtd(net)
    try:
        for _, el in ET.iterparse(net, events=("end",)):
            if el.tag == "lane" and el.get("allow") == "pedestrian":
                return True
            if el.tag in ("edge", "junction", "connection"):
                el.clear()
    except ET.ParseError as exc:
        raise InputError(f"{net} is not a readable SUMO network: {parse_reason(exc)}") \
            from None
    except OSError as exc:
        raise InputError(f"cannot read network {net}: {exc.strerror or exc}") from None
    return False


def strip_header(data):
    """``data`` (bytes of a SUMO output) without its first comment (date, options)."""
    start = data.find(b"<!--")
    root = data.find(b"<", data.find(b"?>") + 2 if data.startswith(b"<?xml") else 0)
    if start < 0 or start != root:
        return data
    stop = data.find(b"-->", start)
    if stop < 0:
        return data
    rest = data[stop + 3:].lstrip(b"\r\n")
    return data[:start] + rest


def _run(cmd, env, what):
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True)
    if proc.returncode != 0:
        lines = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        err = [ln for ln in lines if "rror" in ln] or lines
        msg = err[-1].strip() if err else f"exit code {proc.returncode}"
        raise InputError(f"{what} failed: {msg}")
    return proc


# SUMO's --seed is a C++ int (and randomTrips.py passes it on): 0 to 2**31 - 1.
MAX_SEED = 2**31 - 1


def check_numbers(duration, rate, step, ped_rate=None, seed=0):
    """``InputError`` naming the flag whose value SUMO would fail on, or run on
    wrongly: durations, rates and steps must be finite and positive, the seed an integer
    SUMO takes."""
    for flag, v in (("--duration", duration), ("--rate", rate), ("--step", step),
                    ("--ped-rate", ped_rate)):
        if v is None and flag == "--ped-rate":
            continue
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{flag} {v!r}: must be a positive number")
    if not (isinstance(seed, int) and 0 <= seed <= MAX_SEED):
        raise InputError(f"--seed {seed}: SUMO takes seeds from 0 to {MAX_SEED} (a C++ int)")


@dataclass(frozen=True)
class GenerateSettings:
    """What ``rls traffic generate`` (and a UI panel) asks for: see ``generate``."""
    net: str
    out: str
    duration: float
    rate: float
    seed: int
    step: float = STEP_S
    pedestrians: str = "auto"   # auto, yes, no
    ped_rate: float | None = None
    overwrite: bool = False


def generate_traffic(settings, keep=None):
    """``generate`` with one ``GenerateSettings``: the command's core entry point."""
    return generate(**{f.name: getattr(settings, f.name) for f in fields(settings)},
                    keep=keep)


def generate(net, out, duration, rate, seed, step=STEP_S, pedestrians="auto", ped_rate=None,
             overwrite=False, keep=None):
    """Random traffic over ``net`` simulated by SUMO; writes ``out`` (FCD),
    ``OUT.vtypes.xml`` and ``OUT.rou.xml``. Returns a dict of what ran (counts, seconds
    SUMO took)."""
    import time

    if not os.path.isfile(net):
        raise InputError(f"network file not found: {net}")
    check_numbers(duration=duration, rate=rate, step=step, ped_rate=ped_rate, seed=seed)
    outs = [out, sibling(out, ".vtypes.xml"), sibling(out, ".rou.xml")]
    if not overwrite:
        for p in outs:
            if os.path.exists(p):
                raise InputError(f"{p} already exists; pass --overwrite to replace it")
    home = sumo_home()
    peds = has_sidewalks(net) if pedestrians == "auto" else pedestrians == "yes"
    env = dict(os.environ, SUMO_HOME=home)
    tools = os.path.join(home, "tools")
    env["PYTHONPATH"] = tools + os.pathsep + env.get("PYTHONPATH", "")
    net = os.path.abspath(net)
    tmp = tempfile.mkdtemp(prefix="rls-sumo-")
    t0 = time.perf_counter()
    try:
        vt = os.path.join(tmp, "vtypes.xml")
        with open(vt, "w", encoding="utf-8") as fh:
            fh.write(vtypes_xml())
        random_trips = os.path.join(tools, "randomTrips.py")
        common = ["-n", net, "--seed", str(int(seed)), "-b", "0", "-e", f"{duration:g}",
                  "--validate", "--additional-files", vt]
        routes = [os.path.join(tmp, "vehicles.rou.xml")]
        _run([sys.executable, random_trips, *common, "-p", f"{3600.0 / rate:.6g}",
              "--vclass", "passenger", "--prefix", "v",
              "--trip-attributes", f'type="{DISTRIBUTION}"',
              "-o", os.path.join(tmp, "vehicles.trips.xml"), "-r", routes[0]],
             env, "randomTrips.py (vehicles)")
        if peds:
            pr = ped_rate if ped_rate else rate / 4.0
            routes.append(os.path.join(tmp, "persons.rou.xml"))
            _run([sys.executable, random_trips, *common, "-p", f"{3600.0 / pr:.6g}",
                  "--pedestrians", "--prefix", "p",
                  "--trip-attributes", f'type="{PEDESTRIAN[0]}"',
                  "-o", os.path.join(tmp, "persons.trips.xml"), "-r", routes[1]],
                 env, "randomTrips.py (pedestrians)")
        t_trips = time.perf_counter() - t0
        fcd = os.path.join(tmp, "fcd.xml")
        t1 = time.perf_counter()
        _run([binary(home, "sumo"), "-n", net, "-r", ",".join(routes),
              "--seed", str(int(seed)), "--step-length", f"{step:g}", "--begin", "0",
              "--end", f"{duration:g}", "--fcd-output", fcd, "--no-step-log", "true",
              "--no-warnings", "true", "--duration-log.disable", "true"],
             env, "sumo")
        t_sumo = time.perf_counter() - t1
        merged = _merge_routes(routes)
        with open(fcd, "rb") as fh:
            fcd_bytes = strip_header(fh.read())
        # one set: all three take their names only once all are written
        atomic_write_files({outs[1]: vtypes_xml().encode("utf-8"), outs[2]: merged,
                            out: fcd_bytes}, overwrite=overwrite)
        return {"fcd": out, "vtypes": outs[1], "routes": outs[2], "pedestrians": peds,
                "trips_s": t_trips, "sumo_s": t_sumo,
                "vehicles": merged.count(b"<vehicle "), "persons": merged.count(b"<person ")}
    finally:
        if keep:
            shutil.copytree(tmp, keep, dirs_exist_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)


def _merge_routes(paths):
    """One routes file from duarouter's outputs, their header comments dropped."""
    parts = []
    for p in paths:
        with open(p, "rb") as fh:
            data = strip_header(fh.read())
        a, b = data.find(b">", data.find(b"<routes")) + 1, data.rfind(b"</routes>")
        parts.append(data[a:b].strip(b"\r\n"))
    return b'<?xml version="1.0" encoding="UTF-8"?>\n<routes>\n' + b"\n".join(parts) + \
        b"\n</routes>\n"


def plain_xml(nodes, edges):
    """(nodes XML, edges XML) of a SUMO plain network. ``nodes``: (id, x, y, type);
    ``edges``: (id, from, to, lanes, lane width, sidewalk width or 0, speed m/s)."""
    nod = ["<nodes>"] + [f'    <node id="{i}" x="{x:g}" y="{y:g}" type="{t}"/>'
                         for i, x, y, t in nodes] + ["</nodes>", ""]
    edg = ["<edges>"]
    for i, a, b, lanes, width, walk, speed in edges:
        extra = f' sidewalkWidth="{walk:g}"' if walk else ""
        edg.append(f'    <edge id="{i}" from="{a}" to="{b}" numLanes="{lanes}" '
                   f'width="{width:g}" speed="{speed:g}" spreadType="right"{extra}/>')
    edg += ["</edges>", ""]
    return "\n".join(nod), "\n".join(edg)


def netconvert_plain(nodes, edges, out, crossings=True):
    """Write a plain network (``plain_xml``) and netconvert it to ``out`` in the given
    coordinates (no offset: netOffset 0, 0), with crossings guessed at junctions."""
    home = sumo_home()
    env = dict(os.environ, SUMO_HOME=home)
    tmp = tempfile.mkdtemp(prefix="rls-net-")
    try:
        nod, edg = plain_xml(nodes, edges)
        pn, pe = os.path.join(tmp, "net.nod.xml"), os.path.join(tmp, "net.edg.xml")
        with open(pn, "w", encoding="utf-8") as fh:
            fh.write(nod)
        with open(pe, "w", encoding="utf-8") as fh:
            fh.write(edg)
        _run([binary(home, "netconvert"), "--node-files", pn, "--edge-files", pe,
              "--offset.disable-normalization", "true", "--no-turnarounds", "true",
              "--crossings.guess", "true" if crossings else "false",
              "--no-warnings", "true", "-o", out], env, "netconvert")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out
