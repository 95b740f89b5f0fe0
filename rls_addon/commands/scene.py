"""``rls scene from-net``: a scene (.blend) from a SUMO road network (.net.xml).

Road, crossing and sidewalk surfaces from the network's lanes, junction shapes, walking
areas and crossings (labelled Road and Sidewalk), kerbs along the sidewalks, a mount
pole (rls_mount) at each corner of one junction and an InfraLOB over it. The network
file is only read. Prints a JSON summary; progress on stderr. See docs/roads.md.
"""

import argparse
import json
import os
import sys
import time

from ..core.errors import OutputError


def add_parser(sub):
    p = sub.add_parser("scene", help="build scenes from other tools' files (SUMO networks)",
                       description="Build a scene from another tool's files.")
    act = p.add_subparsers(dest="action", metavar="ACTION")
    act.required = True
    fn = act.add_parser("from-net", help="a scene from a SUMO road network (.net.xml)",
                        description=__doc__.split("\n\n", 1)[1],
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    fn.add_argument("net", help="SUMO network file (.net.xml), e.g. from netconvert or netgenerate")
    fn.add_argument("--out", required=True, help="the scene file to write (.blend)")
    fn.add_argument("--junction", metavar="ID",
                    help="the junction the mounts and the InfraLOB are at (default: the "
                         "largest by area)")
    fn.add_argument("--origin", choices=("net", "junction"), default="net",
                    help="the scene's (0, 0): 'net' (default) keeps SUMO's network "
                         "coordinates; 'junction' puts the chosen junction at the origin")
    fn.add_argument("--overwrite", action="store_true", help="replace an existing scene file")
    p.set_defaults(func=run)


def _say(text):
    print(f"rls: scene: {text}", file=sys.stderr, flush=True)


def run(args):
    from ..core.roads.layout import build_layout
    from ..core.roads.network import read_network

    out = os.path.abspath(args.out)
    if os.path.exists(out) and not args.overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    if not os.path.isdir(os.path.dirname(out)):
        raise OutputError(f"cannot write {out}: folder {os.path.dirname(out)} does not exist")
    t0 = time.perf_counter()
    net = read_network(args.net)
    layout = build_layout(net, args.junction, args.origin)
    t_read = time.perf_counter() - t0

    from ..blender import bpy  # loaded with stop signals held
    from ..blender.files import factory_reset, save_blend
    from ..blender.roads import build_roads

    factory_reset()
    args.prepare_blender()
    _say(f"{len(net.lanes)} lanes, {len(net.junctions)} junctions read in {t_read:.2f} s; "
         f"junction {layout.junction.id}")
    info = build_roads(bpy.context.scene, layout, progress=_say)
    _say(f"writing {out}")
    save_blend(out, overwrite=args.overwrite)
    info.update(scene=out, network=os.path.abspath(args.net),
                seconds=round(time.perf_counter() - t0, 3))
    print(json.dumps(info, indent=1))
    return 0
