"""``rls traffic``: traffic from SUMO in a scene.

``rls traffic import SCENE.blend --fcd FCD.xml --out NEW.blend`` turns SUMO's
floating-car data into one animated, labelled object per vehicle and person (sizes
from ``--vtypes`` files, else ``FCD.vtypes.xml`` beside the FCD, else SUMO's built-in
types); SCENE.blend is never changed and NEW.blend is written whole or not at all.
``rls traffic generate NET.net.xml --duration S --rate VEH_PER_H --seed N --out
FCD.xml`` makes random traffic over a SUMO network and simulates it (SUMO from the
eclipse-sumo wheel, or SUMO_HOME). See docs/traffic.md.
"""

import argparse
import json
import os
import sys
import time

from ..core.errors import InputError, OutputError
from ..core.roads.layout import STEP_S


def add_parser(sub):
    p = sub.add_parser("traffic", help="SUMO traffic: import FCD into a scene, or generate it",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    tsub = p.add_subparsers(dest="traffic_command", metavar="ACTION")
    tsub.required = True
    imp = tsub.add_parser("import", help="animate SUMO FCD output in a copy of a scene")
    imp.add_argument("blend", metavar="SCENE.blend")
    imp.add_argument("--fcd", required=True, metavar="FCD.xml", help="sumo --fcd-output file")
    imp.add_argument("--vtypes", "--routes", action="append", default=[], metavar="FILE",
                     help="route or additional file with the <vType>s (repeatable; default "
                          "FCD.vtypes.xml beside the FCD when it exists)")
    imp.add_argument("--out", required=True, metavar="NEW.blend")
    imp.add_argument("--begin", type=float, help="simulation time (s) at the scene's first "
                                                  "frame (default: the FCD's first step)")
    imp.add_argument("--end", type=float, help="last simulation time (s) keyed (default: "
                                                "the FCD's last step)")
    imp.add_argument("--origin", type=float, nargs=2, default=None, metavar=("X", "Y"),
                     help="network coordinates (m) placed at the scene's origin (default: "
                          "the scene's own, as rls scene from-net recorded it, else 0 0)")
    imp.add_argument("--overwrite", action="store_true", help="replace an existing NEW.blend")
    imp.set_defaults(func=run_import)
    gen = tsub.add_parser("generate", help="random traffic over a SUMO network, simulated")
    gen.add_argument("net", metavar="NET.net.xml")
    gen.add_argument("--duration", type=float, required=True, metavar="S")
    gen.add_argument("--rate", type=float, required=True, metavar="VEH_PER_H",
                     help="vehicles inserted per hour")
    gen.add_argument("--seed", type=int, required=True, metavar="N")
    gen.add_argument("--out", required=True, metavar="FCD.xml")
    gen.add_argument("--step", type=float, default=STEP_S, metavar="S",
                     help=f"SUMO's step length and FCD period (default {STEP_S:g} s: one "
                          f"frame of a scene from rls scene from-net)")
    gen.add_argument("--pedestrians", choices=("auto", "yes", "no"), default="auto",
                     help="persons walking: 'auto' where the network has sidewalks")
    gen.add_argument("--ped-rate", type=float, metavar="PER_H",
                     help="persons per hour (default a quarter of --rate)")
    gen.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    gen.set_defaults(func=run_generate)


def run_generate(args):
    from ..core.traffic.sumo_run import GenerateSettings, generate_traffic

    info = generate_traffic(GenerateSettings(
        net=args.net, out=args.out, duration=args.duration, rate=args.rate, seed=args.seed,
        step=args.step, pedestrians=args.pedestrians, ped_rate=args.ped_rate,
        overwrite=args.overwrite))
    print(json.dumps(info, indent=2))
    return 0


def check_out(scene_path, out, overwrite):
    if os.path.abspath(out) == os.path.abspath(scene_path):
        raise OutputError(f"--out {out} is the scene itself: RLS never changes SCENE.blend; "
                          f"choose another file")
    if not out.lower().endswith(".blend"):
        raise OutputError(f"--out {out} must end in .blend")
    if os.path.exists(out) and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")


def _say(text):
    print(f"rls: traffic: {text}", file=sys.stderr, flush=True)


def run_import(args):
    from ..core.progress import Throttled, left_text
    from ..core.traffic.fcd import check_origin, load

    if not os.path.isfile(args.blend):
        raise InputError(f"scene file not found: {args.blend}")
    check_out(args.blend, args.out, args.overwrite)
    check_origin(args.origin)
    tell = Throttled(_say)

    def reading(share):
        spent = tell.elapsed()
        tell(f"reading {args.fcd}: {share:.0%} in {spent:.0f} s{left_text(share, 1.0, spent)}")

    fcd, types = load(args.fcd, args.vtypes, args.begin, args.end, reading)  # before Blender
    tell(f"{len(fcd.tracks)} vehicles and persons read in {tell.elapsed():.1f} s",
         final=True)
    from ..blender.traffic import import_traffic, traffic_origin
    from .scan import open_scene

    scene = open_scene(args.blend, args.prepare_blender)
    t_keys = time.perf_counter()

    def keying(done, total):
        spent = time.perf_counter() - t_keys
        tell(f"keying objects: {done} of {total}{left_text(done, total, spent)}",
             final=done == total)

    info = import_traffic(scene, fcd, types, origin=traffic_origin(scene, args.origin),
                          begin=args.begin, end=args.end, progress=keying)
    tell(f"writing {args.out}", final=True)
    from ..blender.files import save_blend
    from ..core.output.io.atomic import ensure_directory

    ensure_directory(os.path.dirname(os.path.abspath(args.out)))
    save_blend(args.out, overwrite=args.overwrite)
    info["out"] = args.out
    for notice in info["notices"]:
        print(f"rls: notice: {notice}", file=sys.stderr)
    print(json.dumps(info, indent=2))
    return 0


def run(args):  # the parser sets func per action; kept for the house's interface
    return args.func(args)
