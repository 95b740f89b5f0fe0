"""``rls metrics``: InfraD and InfraNUC of point clouds in an InfraLOB region.

The region is a flat mesh in a .blend (``--lob scene.blend:ObjectName``) or a
JSON file (``--lob-polygon``: ``[[x, y], ...]`` or ``{"polygon": [[x, y], ...]}``),
in world coordinates. Clouds are PCD/PLY files. Their points must end up in
the world frame: when a cloud has a JSON sidecar (same stem, ``.json``) that
says the points are in the sensor frame (``"frame_space": "sensor"``, or
``"frame": "sensor"``), its ``"sensor_to_world"`` 4x4 matrix maps them to world,
or, for a sensor that moved during its sweep, its ``"sensor_poses"`` knots map each
point with the sensor's pose at the point's own time. Clouds without a sidecar are
taken as world-frame. Prints InfraD, InfraNUC and how they were measured as JSON; the
density map's values (a line per cell) only with --grid, or written whole with --out.
"""

import json
import os
import sys


from ..core.choices import DISK_PLACEMENTS
from ..core.errors import InputError, OutputError, RegionError
from ..core.metrics.infra import (
    DEFAULT_CELL_M,
    DEFAULT_DISKS,
    DEFAULT_RADIUS_M,
    DEFAULT_SEED,
    infra_lob_metrics,
)
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("metrics", help="InfraD and InfraNUC of clouds in an InfraLOB region",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--lob", metavar="SCENE.blend:OBJECT", help="region mesh object in a .blend")
    src.add_argument("--lob-polygon", metavar="FILE.json", help="region outline as JSON [[x, y], ...]")
    p.add_argument("--labels", default="road,sidewalk", help="labels to keep, names or ids (default: road,sidewalk)")
    p.add_argument("--disks", type=int, default=DEFAULT_DISKS, help=f"number of disks (default {DEFAULT_DISKS})")
    p.add_argument("--radius", type=float, default=DEFAULT_RADIUS_M, help=f"disk radius in m (default {DEFAULT_RADIUS_M})")
    p.add_argument("--cell", type=float, default=DEFAULT_CELL_M, help=f"density map cell in m (default {DEFAULT_CELL_M})")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"disk placement seed (default {DEFAULT_SEED})")
    p.add_argument("--disk-placement", choices=DISK_PLACEMENTS.ids, default="inside",
                   help="'inside': whole disks in the region (default); 'centre': only centres")
    p.add_argument("--density-png", metavar="OUT.png",
                   help="also write the density map as a PNG chart: points per m^2 per cell, "
                        "axes in world metres, colour bar, InfraD/InfraNUC in the title "
                        "(without matplotlib: the bare map)")
    p.add_argument("--grid", action="store_true",
                   help="also print the density map's values (points per m^2 per cell, "
                        "rows south to north: hundreds of lines) in the JSON")
    p.add_argument("--out", metavar="RESULT.json",
                   help="write the whole result, the density map's values included, as JSON")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing PNG or RESULT.json")
    p.add_argument("clouds", nargs="+", metavar="CLOUD", help="PCD or PLY files")
    p.set_defaults(func=run)


def polygon_from_json(path):
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read region polygon {path}: {exc}") from None
    if isinstance(data, dict):
        data = data.get("polygon")
    if not isinstance(data, list):
        raise InputError(f"{path}: expected [[x, y], ...] or {{\"polygon\": [[x, y], ...]}}")
    return data


def polygon_from_blend(spec):
    path, sep, name = spec.rpartition(":")
    if not sep or not path or not name:
        raise InputError(f"--lob expects SCENE.blend:OBJECT, got {spec!r}")
    from ..core.stop_signals import held

    with held():  # a stop signal waits for Blender to be loaded (as in open_scene)
        from ..blender import bpy  # only here: the rest of this command needs no Blender

        from ..blender.files import open_blend
        from ..blender.region import lob_polygon_world

        open_blend(path, error=InputError)
    obj = bpy.data.objects.get(name)
    if obj is None:
        raise RegionError(f"no object named {name!r} in {path}")
    return lob_polygon_world(obj)


def world_points(path):
    """Read one cloud and bring it to the world frame using its sidecar."""
    from ..core.output.io import read_cloud, read_sidecar
    from ..core.output.io.sidecar import points_to_world

    pts = read_cloud(path)
    info = read_sidecar(path)
    return points_to_world(pts, info, path) if info else pts


def _label_sidecar(path):
    """A cloud's sidecar for labelling a chart, or {} when it has none or it is
    unreadable (the chart then names the file)."""
    from ..core.output.io import read_sidecar

    try:
        return read_sidecar(path) or {}
    except (InputError, OSError, ValueError):
        return {}


def _sensor_name(path, info):
    """The sidecar's sensor, else the file's stem."""
    return str(info.get("sensor") or os.path.splitext(os.path.basename(str(path)))[0])


def cloud_names(paths):
    """A short name per cloud: its sidecar's sensor (device, frame) or the file's stem."""
    names = []
    for path in paths:
        info = _label_sidecar(path)
        name = _sensor_name(path, info)
        device = info.get("device", {}).get("name") if isinstance(info.get("device"), dict) else None
        frame = info.get("frame") if isinstance(info.get("frame"), int) else None
        more = ", ".join(x for x in (device, None if frame is None else f"frame {frame}") if x)
        names.append(f"{name} ({more})" if more else name)
    return list(dict.fromkeys(names))


def sensor_markers(paths):
    """(name, x, y, heading_deg) of each sensor the clouds' sidecars place, once per
    sensor: where its sweep started (``sensor_pose_start``, else ``sensor_to_world``)
    and the way its +X axis pointed. Clouds without a sidecar or pose add nothing."""
    from ..core.metrics.charts import sensor_marker

    markers = {}
    for path in paths:
        info = _label_sidecar(path)
        name = _sensor_name(path, info)
        marker = sensor_marker(name, info.get("sensor_pose_start", info.get("sensor_to_world")))
        if marker is not None:
            markers.setdefault(name, marker)
    return list(markers.values())


def chart_title(args, result):
    """The density chart's title: the region, the clouds, InfraD and InfraNUC."""
    from ..core.metrics.charts import density_title

    if args.lob_polygon:
        region = f"region {os.path.basename(str(args.lob_polygon))}"
    else:
        path, _, name = args.lob.rpartition(":")
        region = f"region {name} in {os.path.basename(path)}"
    names = cloud_names(args.clouds)
    clouds = " + ".join(names) if len(names) <= 3 else f"{len(names)} clouds: {names[0]}, {names[1]}, ..."
    detail = (f"{result.n_points:,} {'/'.join(result.labels)} points in {result.area_m2:.0f} m², "
              f"{result.disks} disks of r {result.radius_m:g} m")
    return density_title(f"{clouds}, {region}", result.infra_d, result.infra_nuc, detail)


def _check_out(args):
    """Refuse an --out that is not JSON, or exists without --overwrite, before any work."""
    if not args.out:
        return
    if not args.out.lower().endswith(".json"):
        raise OutputError(f"--out must name a .json file, got {args.out}")
    if os.path.exists(args.out) and not args.overwrite:
        raise OutputError(f"{args.out} already exists; pass --overwrite to replace it")


def printed(out, grid):
    """What the command prints of the result ``out``: all of it with ``grid``, else
    without the density map's values (its origin, cell and shape stay)."""
    if grid or not out.get("density"):
        return out
    density = {k: v for k, v in out["density"].items() if k != "values"}
    return {**out, "density": density}


def _distinct(paths):
    """Refuse one file given twice (by any path to it): the metrics merge their clouds,
    and a cloud counted twice doubles its points (InfraD, density) without a word."""
    seen = {}
    for p in paths:
        key = os.path.realpath(p)
        if key in seen:
            raise InputError(f"{p} is the cloud {seen[key]} again: give each LiDAR's cloud "
                             "once (the metrics merge them)")
        seen[key] = p


def run(args):
    _check_out(args)
    poly = polygon_from_json(args.lob_polygon) if args.lob_polygon else polygon_from_blend(args.lob)
    _distinct(args.clouds)
    clouds = [world_points(p) for p in args.clouds]
    result = infra_lob_metrics(clouds, poly, labels=args.labels, disks=args.disks, radius=args.radius,
                               seed=args.seed, cell=args.cell, disk_placement=args.disk_placement)
    out = result.to_dict()
    out["clouds"] = [str(p) for p in args.clouds]
    if args.density_png:
        from ..core.metrics.charts import density_png
        from ..core.output.io import atomic_write_bytes

        if not args.density_png.lower().endswith(".png"):
            raise OutputError(f"--density-png must name a .png file, got {args.density_png}")
        png, notice = density_png(result.density, chart_title(args, result),
                                  polygon=result.polygon_xy,
                                  sensors=sensor_markers(args.clouds))
        if notice:
            say(f"rls: notice: {notice}")
        atomic_write_bytes(args.density_png, png, overwrite=args.overwrite)
        out["density_png"] = args.density_png
    if args.out:
        from ..core.output.io import atomic_write_bytes

        out["result"] = args.out
        text = json.dumps(out, indent=1, allow_nan=False) + "\n"
        atomic_write_bytes(args.out, text.encode("utf-8"), overwrite=args.overwrite)
    json.dump(printed(out, args.grid), sys.stdout, indent=2, allow_nan=False)
    sys.stdout.write("\n")
    return 0
