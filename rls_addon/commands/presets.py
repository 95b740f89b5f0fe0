"""``rls presets``: list, show, validate, import and export device presets (no bpy)."""

import json
from pathlib import Path

from ..core.errors import PresetError
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("presets", help="list, show and validate device presets",
                       description="Device presets are TOML data files (see docs/presets.md).")
    act = p.add_subparsers(dest="action", metavar="ACTION")
    act.required = True
    ls = act.add_parser("list", help="list the shipped (and user) presets")
    ls.add_argument("--user-dir", default=None, help="also list presets stored in this folder")
    ls.add_argument("--json", action="store_true", help="print JSON instead of a table")
    sh = act.add_parser("show", help="show one preset's parameters and source")
    sh.add_argument("name", help="preset id, display name or path to a .toml file")
    sh.add_argument("--user-dir", default=None, help="also look in this folder")
    va = act.add_parser("validate", help="check preset files and generate one frame of each")
    va.add_argument("files", nargs="+", metavar="FILE")
    im = act.add_parser("import", help="validate a preset file and store it in a user folder")
    im.add_argument("file")
    im.add_argument("--user-dir", required=True)
    im.add_argument("--overwrite", action="store_true")
    ic = act.add_parser(
        "import-calibration", help="a unit's calibration file as a user preset",
        description="Read a unit's calibration file (Hesai angle-correction CSV, Velodyne "
                    "calibration YAML or db.xml, Ouster sensor metadata JSON, RoboSense "
                    "angle.csv) into a user preset that keeps everything else of --base "
                    "(timing, range, noise, beam, detection). See docs/presets.md.")
    ic.add_argument("file", help="the calibration file")
    ic.add_argument("--base", required=True, help="the preset of the same model to build on")
    ic.add_argument("--id", required=True, dest="new_id", help="the new preset's id")
    ic.add_argument("--name", default=None, help="display name (default: base name + file)")
    ic.add_argument("--user-dir", required=True)
    ic.add_argument("--overwrite", action="store_true")
    ex = act.add_parser("export", help="write a self-contained preset file to share")
    ex.add_argument("name")
    ex.add_argument("file")
    ex.add_argument("--user-dir", default=None)
    ex.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=run)


def _summary(p):
    return {"id": p.id, "name": p.name, "family": p.family, "frequency_hz": p.frequency_hz,
            "rays_per_frame": p.rays_per_frame, "fitted": p.fitted,
            "range_m": [p.range.min_m, p.range.max_m], "source": p.source, "path": p.path,
            "modes": p.modes.to_dict() if getattr(p, "modes", None) else {}}


def run(args):
    from ..core.device import presets as pr

    if args.action == "list":
        items, problems = dict(pr.builtin_presets()), []
        if args.user_dir:
            if not Path(args.user_dir).is_dir():
                raise PresetError(f"{args.user_dir}: no such folder of user presets")
            found, problems = pr.readable_presets_in(args.user_dir)
            for pid, p in found.items():
                if pid in items:
                    problems.append(f"{p.path}: user preset id '{pid}' is shadowed by a "
                                    f"built-in preset")
                items.setdefault(pid, p)
        if args.json:
            print(json.dumps([_summary(p) for p in items.values()], indent=2))
        else:
            for p in items.values():
                rays = "?" if p.rays_per_frame is None else p.rays_per_frame
                fit = " (fitted)" if p.fitted else ""
                print(f"{p.id:22s} {p.family:9s} {p.frequency_hz:5g} Hz {rays:>8} rays/frame  "
                      f"{p.name}{fit}")
        for problem in problems:  # listed, then named: a broken file is never silent
            say(f"rls: error: {problem}")
        return 1 if problems else 0
    if args.action == "show":
        p = pr.get_preset(args.name, args.user_dir)
        out = _summary(p)
        out.update(dropout=vars(p.dropout), attenuation_per_m=p.attenuation_per_m,
                   detection=None if p.detection is None else p.detection.to_dict(),
                   beam=None if p.beam is None else p.beam.to_dict(),
                   scan=p.scan)
        if p.table is not None:
            out["table"] = {"file": p.scan.get("table"), "channels": len(p.table.elevations_deg),
                            "source": p.table.source, "note": p.table.note}
        print(json.dumps(out, indent=2, default=str))
        return 0
    if args.action == "validate":
        bad = 0
        for f in args.files:
            p = pr.load_preset(f)
            pat = p.pattern()
            print(f"{f}: ok ({p.id}, {p.family}, {len(pat)} rays per frame)")
        return bad
    from ..core.device import user_presets as up

    if args.action == "import":
        p = up.import_preset(args.file, args.user_dir, overwrite=args.overwrite)
        print(f"imported '{p.id}' to {p.path}")
        return 0
    if args.action == "import-calibration":
        from ..core.device.calibration_import import import_calibration

        p = import_calibration(args.file, args.base, args.new_id, args.user_dir,
                               name=args.name, overwrite=args.overwrite)
        print(f"imported '{p.id}' ({len(p.table.elevations_deg)} channels from "
              f"{Path(args.file).name}) to {p.path}")
        return 0
    if args.action == "export":
        p = pr.get_preset(args.name, args.user_dir)
        dest = up.export_preset(p, Path(args.file), overwrite=args.overwrite)
        print(f"exported '{p.id}' to {dest}")
        return 0
    raise PresetError(f"unknown presets action '{args.action}'")
