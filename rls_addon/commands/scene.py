"""``rls scene from-net``: a scene (.blend) from a SUMO road network (.net.xml).

Road, crossing and sidewalk surfaces from the network's lanes, junction shapes, walking
areas and crossings (labelled Road and Sidewalk), kerbs along the sidewalks, a mount
pole (rls_mount) at each corner of one junction and an InfraLOB over it. The network
file is only read. Prints a JSON summary; progress on stderr. See docs/roads.md.
"""

import argparse
import json
from .stderr import say


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
                         "signalised one with the most incoming lanes, named on stderr)")
    fn.add_argument("--origin", choices=("net", "junction"), default="net",
                    help="the scene's (0, 0): 'net' (default) keeps SUMO's network "
                         "coordinates; 'junction' puts the chosen junction at the origin")
    fn.add_argument("--overwrite", action="store_true", help="replace an existing scene file")
    p.set_defaults(func=run)


def _say(text):
    say(f"rls: scene: {text}")


def run(args):
    from ..core.roads.scene import FromNetSettings, scene_from_net

    settings = FromNetSettings(net=args.net, out=args.out, junction=args.junction,
                               origin=args.origin, overwrite=args.overwrite)

    def blender_scene():
        from ..blender import bpy  # loaded with stop signals held
        from ..blender.files import factory_reset
        from ..blender.roads import BlenderRoadScene

        factory_reset()
        args.prepare_blender()
        return BlenderRoadScene(bpy.context.scene)

    info = scene_from_net(settings, blender_scene, _say)
    print(json.dumps(info, indent=1))
    return 0
