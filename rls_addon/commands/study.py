"""``rls study``: where to mount k LiDARs over an InfraLOB.

Every candidate placement (a mount or grid point, times each pitch and yaw) of one
device is scanned once over the static scene (vehicles and pedestrians left out),
InfraD and InfraNUC are measured in the InfraLOB, and sets of k sensors are searched
for high density and low non-uniformity. Writes to --out:

  candidates.csv   one row per candidate: pose, points in the region, InfraD, InfraNUC
  placements.csv   every evaluated k-set: members, InfraD, InfraNUC, Pareto flag, best
  study.json       settings, timing, candidates, per-k Pareto front and best set,
                   the best sets' density maps
  pareto.png       InfraD against InfraNUC for all candidates and sets, fronts marked
  density_k<K>.png density map of the best set of each k, sensors marked

Charts need matplotlib (Agg); without it the density maps are written with RLS's own
PNG writer and pareto.png is skipped (a notice says so). Prints a JSON summary.
"""

import argparse
import csv
import io
import json
import math
import os
import sys

from ..core.choices import BACKENDS
from ..core.errors import SceneError
from ..core.metrics import DEFAULT_CELL_M, DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED
from ..core.placement import DEFAULT_EXHAUSTIVE_LIMIT
from ..core.study import parse_values
from .scan import check_output_dir, open_scene


def add_parser(sub):
    p = sub.add_parser("study", help="search LiDAR placements over an InfraLOB (InfraD, InfraNUC)",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("blend", nargs="?", help="scene file (omit inside 'blender -b scene.blend -c rls')")
    p.add_argument("--out", required=True, help="output directory for the report")
    p.add_argument("--device", default="generic_uniform32", help="device preset id or name")
    p.add_argument("--k", default="1", help="sensors per placement: 2, 1,2,3 or 1:3:1 (default 1)")
    p.add_argument("--lob", help="InfraLOB object (default: the object marked rls_infralob)")
    p.add_argument("--mount", action="append", default=[],
                   help="mount object name (repeatable; default: every object marked rls_mount)")
    p.add_argument("--grid", type=float, metavar="STEP",
                   help="also/instead place candidates on a grid of STEP metres over the region")
    p.add_argument("--heights", default="6", help="grid heights in m (default 6)")
    p.add_argument("--grid-margin", type=float, default=0.0, help="grow the grid beyond the region (m)")
    p.add_argument("--pitch", default="0", help="downward pitch in degrees: 0, 0,10,20 or 0:30:10")
    p.add_argument("--yaw", default="0", help="yaw in degrees (same forms as --pitch)")
    p.add_argument("--yaw-mode", choices=("face", "absolute"), default="face",
                   help="'face' (default): yaw is relative to facing the region's centre")
    p.add_argument("--roll", type=float, default=0.0, help="roll in degrees")
    p.add_argument("--labels", default="road,sidewalk", help="labels counted in the region")
    p.add_argument("--disks", type=int, default=DEFAULT_DISKS)
    p.add_argument("--radius", type=float, default=DEFAULT_RADIUS_M)
    p.add_argument("--disk-seed", type=int, default=DEFAULT_SEED)
    p.add_argument("--disk-placement", choices=("inside", "centre"), default="inside")
    p.add_argument("--cell", type=float, default=DEFAULT_CELL_M, help="density map cell (m)")
    p.add_argument("--seed", type=int, default=0, help="scan seed (noise, dropout)")
    p.add_argument("--no-noise", action="store_true")
    p.add_argument("--no-dropout", action="store_true")
    p.add_argument("--keep-traffic", action="store_true",
                   help="keep vehicles and pedestrians (the paper removes them)")
    p.add_argument("--frame", type=int, help="scene frame (default: the current one)")
    p.add_argument("--allow-shared-mounts", action="store_true",
                   help="let a set use several orientations on the same mount")
    p.add_argument("--exhaustive-limit", type=int, default=DEFAULT_EXHAUSTIVE_LIMIT,
                   help="evaluate every k-set up to this many, else greedy+swap")
    p.add_argument("--backend", choices=BACKENDS.ids, default="auto",
                   help="ray casting: Embree when available (auto), or Blender's BVHTree")
    p.add_argument("--overwrite", action="store_true", help="replace an existing report")
    p.set_defaults(func=run)


def config_from_args(args):
    from ..core.study import StudyConfig

    ks = sorted({int(v) for v in parse_values(args.k, "--k")})
    if any(k < 1 or k != float(k) for k in ks):
        raise SceneError(f"--k: sensor counts must be positive integers, got {args.k}")
    return StudyConfig(
        device=args.device, k=tuple(ks), lob=args.lob, mounts=tuple(args.mount),
        grid_step=args.grid, grid_heights=tuple(parse_values(args.heights, "--heights")),
        grid_margin=args.grid_margin, pitches=tuple(parse_values(args.pitch, "--pitch")),
        yaws=tuple(parse_values(args.yaw, "--yaw")), yaw_mode=args.yaw_mode, roll=args.roll,
        labels=args.labels, disks=args.disks, radius=args.radius, disk_seed=args.disk_seed,
        disk_placement=args.disk_placement, cell=args.cell, scan_seed=args.seed,
        noise=not args.no_noise, dropout=not args.no_dropout, keep_traffic=args.keep_traffic,
        backend=args.backend, frame=args.frame, one_per_mount=not args.allow_shared_mounts,
        exhaustive_limit=args.exhaustive_limit)


REPORT_FILES = ("candidates.csv", "placements.csv", "study.json", "pareto.png")


def _progress(done, total, cand, eta):
    print(f"[{done}/{total}] {cand.name}: {cand.n_points} points in the region "
          f"({cand.scan_points} in all) in {cand.seconds:.2f} s, about {eta:.1f} s left",
          file=sys.stderr, flush=True)


def run(args):
    from ..blender.study import run_study

    cfg = config_from_args(args)
    scene = open_scene(args.blend)
    check_output_dir(args.out)
    if not args.overwrite:
        names = list(REPORT_FILES) + [f"density_k{k}.png" for k in cfg.k]
        clash = [f for f in names if os.path.exists(os.path.join(args.out, f))]
        if clash:
            raise SceneError(f"{os.path.join(args.out, clash[0])} already exists; "
                             "pass --overwrite to replace the report")
    result = run_study(scene, cfg, progress=_progress)
    for note in result.notices:
        print(f"rls: notice: {note}", file=sys.stderr)
    summary = write_report(result, args.out, overwrite=args.overwrite)
    print(json.dumps(summary, indent=2))
    return 0


def _fmt(v, nd=6):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return round(v, nd) if isinstance(v, float) else v


def _csv(rows, fields):
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({f: _fmt(r.get(f)) for f in fields})
    return buf.getvalue().encode("utf-8")


def placement_rows(result):
    names = [c.name for c in result.candidates]
    rows = []
    for k, s in sorted(result.searches.items()):
        front = {p.members for p in s.front}
        for p in sorted(s.evaluated, key=lambda p: (-p.infra_d, p.infra_nuc)):
            rows.append({"k": k, "sensors": " + ".join(names[i] for i in p.members),
                         "members": " ".join(str(i) for i in p.members),
                         "points_in_lob": p.n_points, "infra_d": p.infra_d,
                         "infra_nuc": p.infra_nuc, "pareto": int(p.members in front),
                         "best": int(p.members == s.best.members), "method": s.method})
    return rows


def report_dict(result):
    names = [c.name for c in result.candidates]
    cfg = result.config
    out = {
        "scene": result.scene, "frame": result.frame, "device": result.device,
        "region": {"polygon_xy": result.polygon.tolist(), "area_m2": result.layout.area_m2,
                   "labels": cfg.labels, "disks": cfg.disks, "radius_m": cfg.radius,
                   "disk_seed": cfg.disk_seed, "disk_placement": cfg.disk_placement},
        "settings": {"k": list(cfg.k), "pitch_deg": list(cfg.pitches), "yaw_deg": list(cfg.yaws),
                     "yaw_mode": cfg.yaw_mode, "roll_deg": cfg.roll, "scan_seed": cfg.scan_seed,
                     "noise": cfg.noise, "dropout": cfg.dropout,
                     "one_sensor_per_mount": cfg.one_per_mount,
                     "traffic_removed": not cfg.keep_traffic},
        "hidden_traffic": result.hidden_traffic,
        "backend": result.backend, "structure_builds": result.structure_builds,
        "timing_s": {k: round(v, 4) for k, v in result.timing.items()},
        "candidates": [c.row() for c in result.candidates],
        "placements": {},
    }
    for k, s in sorted(result.searches.items()):
        out["placements"][str(k)] = {
            "method": s.method, "sets": s.sets_total, "evaluated": len(s.evaluated),
            "pareto_front": [p.to_dict(names) for p in s.front],
            "best": s.best.to_dict(names),
            "best_density": result.density(s.best.members).to_dict(),
        }
    return out


def write_report(result, out_dir, overwrite=False):
    from ..core.io import atomic_write_bytes

    cand_fields = list(result.candidates[0].row().keys())
    files = {}
    files["candidates.csv"] = _csv([c.row() for c in result.candidates], cand_fields)
    files["placements.csv"] = _csv(placement_rows(result),
                                   ["k", "sensors", "members", "points_in_lob", "infra_d",
                                    "infra_nuc", "pareto", "best", "method"])
    report = report_dict(result)
    charts, notice = charts_png(result)
    files.update(charts)
    report["charts"] = sorted(charts)
    if notice:
        report["notice"] = notice
        print(f"rls: notice: {notice}", file=sys.stderr)
    files["study.json"] = (json.dumps(report, indent=2, allow_nan=False) + "\n").encode("utf-8")
    written = []
    for name in sorted(files):
        path = os.path.join(out_dir, name)
        atomic_write_bytes(path, files[name], overwrite=overwrite)
        written.append(os.path.abspath(path))
    names = [c.name for c in result.candidates]
    return {
        "scene": result.scene, "device": result.device["id"],
        "candidates": len(result.candidates),
        "seconds": round(result.timing["total_s"], 3),
        "per_candidate_s": round(result.timing["per_candidate_s"], 4),
        "structure_builds": result.structure_builds,
        "best": {str(k): {"sensors": [names[i] for i in s.best.members],
                          "infra_d": round(s.best.infra_d, 4),
                          "infra_nuc": round(s.best.infra_nuc, 4), "method": s.method}
                 for k, s in sorted(result.searches.items())},
        "report": os.path.abspath(os.path.join(out_dir, "study.json")),
        "files": written,
    }


def charts_png(result):
    """{file name: PNG bytes}, and a notice when matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt  # noqa: F401
    except ImportError:
        out = {f"density_k{k}.png": result.density(s.best.members).to_png()
               for k, s in result.searches.items()}
        return out, ("matplotlib is not installed: pareto.png skipped, density maps drawn "
                     "without axes (pip install matplotlib)")
    return {"pareto.png": _pareto_png(result),
            **{f"density_k{k}.png": _density_png(result, k, s)
               for k, s in result.searches.items()}}, None


def _fig_bytes(fig):
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _pareto_png(result):
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(7, 5))
    colours = plt.get_cmap("tab10")
    for j, (k, s) in enumerate(sorted(result.searches.items())):
        d = np.array([p.infra_d for p in s.evaluated])
        u = np.array([p.infra_nuc for p in s.evaluated])
        ax.scatter(d, u, s=14, alpha=0.45, color=colours(j), label=f"k = {k} ({s.method})")
        fd = [p.infra_d for p in s.front]
        fu = [p.infra_nuc for p in s.front]
        ax.plot(fd, fu, "-o", color=colours(j), markersize=6, markerfacecolor="none",
                label=f"Pareto front, k = {k}")
        ax.scatter([s.best.infra_d], [s.best.infra_nuc], marker="*", s=160, color=colours(j),
                   edgecolor="black", zorder=5)
    ax.set_xlabel("InfraD (points / m², higher is denser)")
    ax.set_ylabel("InfraNUC (lower is more uniform)")
    ax.set_title(f"{result.scene}: {result.device['name']}, {len(result.candidates)} candidates"
                 " (★ best)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _fig_bytes(fig)


def _density_png(result, k, search):
    import matplotlib.pyplot as plt
    import numpy as np

    dm = result.density(search.best.members)
    ny, nx = dm.values.shape
    x0, y0 = dm.origin_xy
    ext = [x0, x0 + nx * dm.cell_m, y0, y0 + ny * dm.cell_m]
    fig, ax = plt.subplots(figsize=(7, 5.5))
    im = ax.imshow(np.ma.masked_invalid(dm.values), origin="lower", extent=ext, cmap="viridis")
    fig.colorbar(im, ax=ax, label="points / m²")
    poly = np.vstack([result.polygon, result.polygon[:1]])
    ax.plot(poly[:, 0], poly[:, 1], color="white", lw=1)
    for i in search.best.members:
        c = result.candidates[i]
        x, y, _ = c.position
        ax.plot([x], [y], marker="^", color="red", markersize=9, markeredgecolor="black")
        a = math.radians(c.yaw_deg)
        ax.annotate(f"{c.name}", (x, y), textcoords="offset points", xytext=(4, 4),
                    fontsize=7, color="red")
        if c.pitch_deg:
            ax.arrow(x, y, 2 * math.cos(a), 2 * math.sin(a), color="red", head_width=0.5)
    b = search.best
    ax.set_title(f"{result.scene}, best k = {k}: InfraD {b.infra_d:.2f}, InfraNUC {b.infra_nuc:.3f}")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    lo = np.minimum(result.polygon.min(0), [min(result.candidates[i].position[0] for i in b.members),
                                            min(result.candidates[i].position[1] for i in b.members)])
    hi = np.maximum(result.polygon.max(0), [max(result.candidates[i].position[0] for i in b.members),
                                            max(result.candidates[i].position[1] for i in b.members)])
    ax.set_xlim(lo[0] - 1, hi[0] + 1)
    ax.set_ylim(lo[1] - 1, hi[1] + 1)
    fig.tight_layout()
    return _fig_bytes(fig)
