"""``rls evaluate``: score detections against RLS's ground truth in a region of interest.

Ground truth (--truth, repeatable: several LiDARs are scored as one): an RLS 'kitti'
dataset (a sensor folder with meta/, or a dataset folder: every sensor in it) or scan
sidecars (a folder of them; every sensor in it). Detections (--detections): a folder of
NNNNNN.txt ('x y z dx dy dz heading Class score' in the dataset's label frame),
OpenPCDet's result.pkl, or OpenCOOD's npy folder (NNNN_pred.npy), placed in the world
with the poses of --dataset (default: the --truth folder when it is one kitti sensor).

A ground-truth box counts when its centre lies in the region (--lob or --region;
default everywhere) and it has at least --min-points returns; other boxes are
don't-care. Detections centred outside the region are dropped unless they find a
counted box. Prints a table of AP_R40 (KITTI's 40 recall points) and AP_VOC (VOC
all-point, as OpenCOOD) per class and IoU; --out writes everything as JSON (curves,
counts per frame, each detection's match). See docs/evaluate.md."""

import argparse
from pathlib import Path

from ..core.errors import InputError, OutputError
from .stderr import say

FORMAT_CHOICES = ("auto", "kitti", "openpcdet", "opencood")


def add_parser(sub):
    p = sub.add_parser("evaluate", help="score detections against RLS's ground truth",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--truth", action="append", required=True, metavar="PATH",
                   help="RLS kitti dataset (sensor folder or dataset folder) or scan "
                        "sidecars; repeat for several LiDARs (scored as one)")
    p.add_argument("--detections", required=True, metavar="PATH",
                   help="folder of NNNNNN.txt, OpenPCDet's result.pkl, or OpenCOOD's npy folder")
    p.add_argument("--format", choices=FORMAT_CHOICES, default="auto",
                   help="detection format (default: found from the path)")
    p.add_argument("--dataset", metavar="ROOT",
                   help="the dataset the detector ran on, whose poses place its boxes: an "
                        "RLS kitti sensor folder (default: --truth when it is one) or, "
                        "for opencood, the OPV2V test root")
    p.add_argument("--scenario", metavar="NAME",
                   help="opencood: the scenario to score when the predictions span several")
    region = p.add_mutually_exclusive_group()
    region.add_argument("--lob", metavar="SCENE.blend:OBJECT",
                        help="the region: a flat mesh in a .blend (opens Blender)")
    region.add_argument("--region", metavar="\"x,y x,y x,y ...\"",
                        help="the region: its outline in world x-y metres")
    p.add_argument("--min-points", type=int, default=5,
                   help="returns a ground-truth box needs to count (default 5, as TUMTraf)")
    p.add_argument("--classes", default="vehicle,pedestrian,cyclist",
                   help="classes to score, comma separated (default: vehicle,pedestrian,cyclist)")
    p.add_argument("--iou", default="0.3,0.5,0.7",
                   help="IoU thresholds, comma separated (default 0.3,0.5,0.7)")
    p.add_argument("--distance-bins", metavar="EDGES",
                   help="also score by horizontal distance from the sensor: bin edges in "
                        "metres, e.g. 0,30,50 (an open last bin: 0,30,50,inf)")
    p.add_argument("--out", metavar="RESULT.json",
                   help="write the whole result as JSON (nothing is written on an error)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    p.set_defaults(func=run)


def _numbers(text, option):
    try:
        values = [float(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        raise InputError(f"{option} expects numbers separated by commas, got {text!r}") from None
    if not values:
        raise InputError(f"{option} expects numbers separated by commas, got {text!r}")
    return values


def parse_region(text):
    """[[x, y], ...] of ``--region "x,y x,y x,y"`` (world metres)."""
    out = []
    for pair in str(text).replace(";", " ").split():
        parts = pair.split(",")
        try:
            if len(parts) != 2:
                raise ValueError
            out.append([float(parts[0]), float(parts[1])])
        except ValueError:
            raise InputError(f"--region expects vertices 'x,y x,y x,y ...' (world metres), "
                             f"got {pair!r} in {text!r}") from None
    return out


def _check_out(args):
    """Refuse an existing --out without --overwrite before any work."""
    if not args.out:
        return
    out = Path(args.out)
    if out.is_dir():
        raise OutputError(f"--out {out} is a folder; name the JSON file to write")
    if out.exists() and not args.overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")


def _region(args):
    """(polygon or None, a description of it)."""
    if args.lob:
        from .metrics import polygon_from_blend  # opens Blender: only for --lob

        path, _, name = args.lob.rpartition(":")
        return polygon_from_blend(args.lob), f"{name} in {Path(path).name}"
    if args.region:
        return parse_region(args.region), "given by --region"
    return None, None


def _ap(value):
    return "    -" if value is None else f"{value:.4f}"


def summary(result, header):
    """The readable table: class, distance range, IoU, both APs, tp/fp/gt."""
    lines = list(header)
    kinds, keys = result["kinds"], [f"{t:g}" for t in result["iou_thresholds"]]
    rows, quiet = [], []
    for name, c in result["classes"].items():
        first = c["all"][kinds[0]][keys[0]]
        if first["gt"] == 0 and first["tp"] + first["fp"] == 0:
            quiet.append(name)
            continue
        scopes = [("all", c["all"])] + [
            (f"{b['range_m'][0]:g}-{b['range_m'][1]:g} m" if b["range_m"][1] is not None
             else f"{b['range_m'][0]:g}+ m", b) for b in c["bins"]]
        for scope, rec in scopes:
            for kind in kinds:
                for key in keys:
                    r = rec[kind][key]
                    rows.append(f"{name:<11}{scope:<11}{kind.upper():<4}{key:<6}"
                                f"{_ap(r['ap_r40']):>8}{_ap(r.get('ap_r40_kitti')):>8}"
                                f"{_ap(r['ap_voc']):>8}{r['tp']:>7}{r['fp']:>7}{r['gt']:>7}")
    if rows:
        lines += ["", f"{'class':<11}{'range':<11}{'IoU':<10}{'AP_R40':>8}{'KITTI':>8}"
                      f"{'AP_VOC':>8}{'tp':>7}{'fp':>7}{'gt':>7}"] + rows
    motion = []
    for name, c in result["classes"].items():
        for key in keys:
            by = c["all"][kinds[0]][key].get("by_motion", {})
            parts = [f"{what} {r['tp']}/{r['gt']}" + (f" ({r['recall']:.2f})" if r["gt"] else "")
                     for what, r in by.items() if r["gt"]]
            if parts:
                motion.append(f"{name:<11}{kinds[0].upper():<4}{key:<6}{'; '.join(parts)}")
    if motion:
        lines += ["", "counted boxes found, standing (under 0.1 m/s) and moving:"] + motion
    if quiet:
        lines.append(f"no counted ground truth and no detections: {', '.join(quiet)} "
                     "(AP undefined)")
    lines.append("AP_R40: KITTI's 40 recall points (Simonelli et al.); KITTI: the same as "
                 "OpenPCDet's kitti_object_eval_python computes it; AP_VOC: VOC all-point "
                 "as OpenCOOD; fractions of 1; '-': no counted ground truth")
    return "\n".join(lines)


def run(args):
    from ..core.evaluate.runs import EvaluateSettings, evaluate
    from ..core.evaluate.scoring import frames_text

    _check_out(args)
    classes = [c for c in args.classes.split(",") if c.strip()]
    thresholds = _numbers(args.iou, "--iou")
    bins = _numbers(args.distance_bins, "--distance-bins") if args.distance_bins else None
    polygon, region_name = _region(args)
    result = evaluate(EvaluateSettings(
        truth=tuple(args.truth), detections=args.detections, format=args.format,
        dataset=args.dataset, scenario=args.scenario,
        region=None if polygon is None else tuple(map(tuple, polygon)),
        region_name=region_name, min_points=args.min_points, classes=tuple(classes),
        iou_thresholds=tuple(thresholds), distance_bins=None if bins is None else tuple(bins)))
    fmt = result["inputs"]["format"]
    for notice in result["notices"]:
        say(f"rls: notice: {notice}")
    g, d = result["ground_truth"], result["detections"]
    where = "everywhere" if polygon is None else \
        f"region {region_name} ({result['region']['area_m2']:.0f} m^2, box centres inside)"
    header = [
        f"rls evaluate: {len(g['frames'])} frames ({frames_text(g['frames'])}) of "
        f"{', '.join(g['sensors'])}; {where}; boxes with >= {result['min_points']} points",
        f"ground truth: {g['counted']} counted, {g['ignored_outside_region']} centred "
        f"outside the region and {g['ignored_few_points']} with fewer points (don't-care)",
        f"detections ({fmt}): {d['boxes']}, {d['outside_region']} centred outside the "
        "region (dropped unless they find a counted box)"]
    about = result["inputs"]["detector"]
    if about and isinstance(about.get("background"), dict):
        header.append(f"detector: {about.get('detector')}; background: "
                      f"{about['background'].get('label')} "
                      f"({about['background'].get('what')})")
    if args.out:
        from ..core.evaluate.runs import result_json
        from ..core.output.io.atomic import atomic_write_bytes

        atomic_write_bytes(args.out, result_json(result), overwrite=args.overwrite)
        header.append(f"result: {args.out}")
    print(summary(result, header))
    return 0


__all__ = ["add_parser", "parse_region", "run", "summary"]
