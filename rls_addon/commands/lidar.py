"""``rls lidar``: add, list and remove the LiDARs of a scene from the command line.

    rls lidar add SCENE.blend --preset ID (--mount OBJECT | --at X,Y,Z) [--pitch DEG]
                  [--yaw DEG | --face-region] [--name NAME] --out OUT.blend [--overwrite]
    rls lidar list SCENE.blend [--json]
    rls lidar remove SCENE.blend --sensor NAME [--sensor NAME ...] --out OUT.blend [--overwrite]

A LiDAR is an empty whose axes are the sensor frame (+X forward, +Z up), as *Add >
LiDAR* makes it. On a mount it sits on the object's top (plus the object's
rls_mount_offset, 0.25 m by default); --pitch tilts +X below the horizon, --yaw turns it
counter-clockwise from world +X, --face-region turns it towards the middle of the
InfraLOB. SCENE is read; the result is written whole to --out (the scene itself only
with --overwrite)."""

import argparse
import json
import os

from ..core.errors import OutputError


def add_parser(sub):
    p = sub.add_parser("lidar", help="add, list and remove a scene's LiDARs",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    act = p.add_subparsers(dest="action", metavar="ACTION")
    act.required = True
    add = act.add_parser("add", help="add a LiDAR on a mount or at a point")
    add.add_argument("blend", metavar="SCENE.blend")
    add.add_argument("--preset", required=True, metavar="ID",
                     help="device preset id or name (rls presets list)")
    where = add.add_mutually_exclusive_group(required=True)
    where.add_argument("--mount", metavar="OBJECT",
                       help="the object it sits on (a pole marked rls_mount, or any object)")
    where.add_argument("--at", metavar="X,Y,Z", help="its position in world metres")
    add.add_argument("--pitch", type=float, default=0.0, metavar="DEG",
                     help="degrees its +X looks below the horizon (default 0)")
    aim = add.add_mutually_exclusive_group()
    aim.add_argument("--yaw", type=float, default=None, metavar="DEG",
                     help="degrees counter-clockwise from world +X (default 0)")
    aim.add_argument("--face-region", action="store_true",
                     help="turn it towards the middle of the InfraLOB")
    add.add_argument("--lob", metavar="OBJECT",
                     help="the InfraLOB to face (default: the one marked rls_infralob)")
    add.add_argument("--name", default="LiDAR", help="its object name (default LiDAR)")
    _out_arguments(add)
    add.set_defaults(func=run_add)
    ls = act.add_parser("list", help="the scene's LiDARs: device, position, aim, output")
    ls.add_argument("blend", metavar="SCENE.blend")
    ls.add_argument("--json", action="store_true", help="print JSON instead of a table")
    ls.set_defaults(func=run_list)
    rm = act.add_parser("remove", help="remove LiDARs with their outlines and previews")
    rm.add_argument("blend", metavar="SCENE.blend")
    rm.add_argument("--sensor", action="append", required=True, metavar="NAME",
                    help="the LiDAR to remove (repeatable)")
    _out_arguments(rm)
    rm.set_defaults(func=run_remove)


def _out_arguments(p):
    p.add_argument("--out", required=True, metavar="OUT.blend",
                   help="the scene file to write (SCENE itself with --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUT.blend")


def check_out(out, overwrite):
    """Refuse an output that is not a .blend, or exists without ``overwrite``, before
    anything is read."""
    if not out.lower().endswith(".blend"):
        raise OutputError(f"--out {out} must end in .blend")
    if os.path.isdir(out):
        raise OutputError(f"--out {out} is a folder; name the .blend file to write")
    if os.path.exists(out) and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")


def _save(args):
    from ..blender.files import save_blend
    from ..core.output.io.atomic import ensure_directory

    ensure_directory(os.path.dirname(os.path.abspath(args.out)))
    return save_blend(args.out, overwrite=args.overwrite)


def _open(args):
    from .scan import open_scene

    return open_scene(args.blend, args.prepare_blender)


def run_add(args):
    from ..core.scene.mounting import LidarMounting, parse_position

    check_out(args.out, args.overwrite)
    mounting = LidarMounting(
        preset=args.preset, name=args.name, mount=args.mount,
        at=parse_position(args.at) if args.at is not None else None,
        pitch_deg=args.pitch, yaw_deg=args.yaw, face_region=args.face_region)
    scene = _open(args)
    from ..blender.lidars import add_lidar, lidar_rows

    obj = add_lidar(scene, mounting, lob=args.lob)
    out = _save(args)
    row = next(r for r in lidar_rows(scene) if r["name"] == obj.name)
    print(json.dumps({"added": row, "scene": out}, indent=2))
    return 0


def run_remove(args):
    check_out(args.out, args.overwrite)
    scene = _open(args)
    from ..blender.lidars import lidar_rows, remove_lidars

    removed = remove_lidars(scene, args.sensor)
    out = _save(args)
    print(json.dumps({"removed": removed, "left": [r["name"] for r in lidar_rows(scene)],
                      "scene": out}, indent=2))
    return 0


def run_list(args):
    scene = _open(args)
    from ..blender.lidars import lidar_rows

    rows = lidar_rows(scene)
    if args.json:
        print(json.dumps({"scene": os.path.abspath(args.blend), "lidars": rows}, indent=2))
        return 0
    print(table(rows, args.blend))
    return 0


def table(rows, blend):
    """The LiDARs as a readable table."""
    if not rows:
        return (f"{blend}: no LiDARs (add one: rls lidar add {blend} --preset ID --mount "
                "OBJECT --out OUT.blend)")
    head = f"{'name':<16} {'device':<28} {'x':>9} {'y':>9} {'z':>7} {'yaw':>7} {'pitch':>6}  output"
    lines = [head]
    for r in rows:
        x, y, z = r["position_m"]
        lines.append(f"{r['name']:<16} {r['device'][:28]:<28} {x:>9.2f} {y:>9.2f} {z:>7.2f} "
                     f"{r['yaw_deg']:>7.1f} {r['pitch_deg']:>6.1f}  {r['output_dir']}"
                     + (f"  (on {r['parent']})" if r["parent"] else ""))
    lines.append("x, y, z: world metres; yaw: degrees counter-clockwise from world +X; "
                 "pitch: degrees below the horizon")
    return "\n".join(lines)


__all__ = ["add_parser", "check_out", "run_add", "run_list", "run_remove", "table"]
