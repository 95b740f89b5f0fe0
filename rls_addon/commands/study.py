"""``rls study``: where to mount k LiDARs over an InfraLOB.

Every candidate placement (a mount or grid point, times each pitch and yaw) of one
device (--device, default generic_uniform32; not the scene's LiDAR objects) is scanned once over the static scene (vehicles, pedestrians and cyclists left
out), InfraD and InfraNUC are measured in the InfraLOB, and sets of k sensors are
searched for high density and low non-uniformity. With --traffic FRAMES each candidate
is also scanned over those frames of the scene's animated traffic and scored by how
well it sees the vehicles in the region (the share of vehicle-frames with at least 5,
20, 50 points, mean points per vehicle, the share never seen); sets combine by
per-vehicle unions. With --evaluate FRAMES the placements are also judged by detection:
RLS's roadside detector on each candidate and on the sets the study reports (early
fusion), the vehicle AP_R40 at BEV IoU 0.5 in the region, and how well InfraD,
InfraNUC and visibility predict it (docs/evaluate.md). Writes to --out:

  candidates.csv   one row per candidate: pose, points in the region, InfraD, InfraNUC
                   (and with --traffic: visibility and the ranks by InfraD and by it)
  placements.csv   every evaluated k-set: members, InfraD, InfraNUC, Pareto flag, best
  study.json       settings, timing, candidates, per-k Pareto front and best set,
                   the best sets' density maps (and the best sets by visibility)
  pareto.png       InfraD against InfraNUC for all candidates and sets, fronts marked
  density_k<K>.png density map of the best set of each k, sensors marked
  visibility.png   with --traffic: InfraD, InfraNUC and visibility per candidate/set
  ap_vs_<metric>.png  with --evaluate: AP against each metric, one point per placement

Charts need matplotlib (Agg); without it the density maps are written with RLS's own
PNG writer and the other charts are skipped (a notice says so). Prints a JSON summary.
"""

import argparse
import json
import os

from ..core.choices import BACKENDS, BACKGROUNDS, DISK_PLACEMENTS, YAW_MODES
from ..core.errors import SceneError
from ..core.metrics.infra import (
    DEFAULT_CELL_M,
    DEFAULT_DISKS,
    DEFAULT_RADIUS_M,
    DEFAULT_SEED,
)
from ..core.scan.background_sweeps import BACKGROUND_SWEEPS
from ..core.study.placement import DEFAULT_EXHAUSTIVE_LIMIT
from ..core.study.report import report_clash, write_report
from .distribute import add_arguments as add_cluster_arguments
from ..core.study.config import parse_values  # noqa: F401  (tests read it from here)
from .scan import check_output_dir, open_scene
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("study", help="search LiDAR placements over an InfraLOB (InfraD, InfraNUC)",
                       description=__doc__.split("\n\n", 1)[1],
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("blend", nargs="?", help="scene file (omit inside 'blender -b scene.blend -c rls')")
    p.add_argument("--out", required=True, help="output directory for the report")
    p.add_argument("--device", default="generic_uniform32",
                   help="device preset id or name placed at every candidate (default "
                        "generic_uniform32, the paper's uniform 32-channel LiDAR); the "
                        "scene's own LiDAR objects are not used")
    p.add_argument("--rotation-hz", type=float, default=None, metavar="HZ",
                   help="spinning devices: the rotation rate (a mode of the preset or a "
                        "measured rate such as 10.017; default: the preset's)")
    p.add_argument("--lidar-mode", default=None, metavar="MODE",
                   help="devices with lidar modes (Ouster): e.g. 1024x10 (default: the preset's)")
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
    p.add_argument("--yaw-mode", choices=YAW_MODES.ids, default="face",
                   help="'face' (default): yaw is relative to facing the region's centre")
    p.add_argument("--roll", type=float, default=0.0, help="roll in degrees")
    p.add_argument("--labels", default="road,sidewalk", help="labels counted in the region")
    p.add_argument("--disks", type=int, default=DEFAULT_DISKS)
    p.add_argument("--radius", type=float, default=DEFAULT_RADIUS_M)
    p.add_argument("--disk-seed", type=int, default=DEFAULT_SEED)
    p.add_argument("--disk-placement", choices=DISK_PLACEMENTS.ids, default="inside")
    p.add_argument("--cell", type=float, default=DEFAULT_CELL_M, help="density map cell (m)")
    p.add_argument("--seed", type=int, default=0, help="scan seed (noise, dropout)")
    p.add_argument("--no-noise", action="store_true")
    p.add_argument("--no-dropout", action="store_true")
    p.add_argument("--keep-traffic", action="store_true",
                   help="keep vehicles, pedestrians and cyclists (the paper removes them)")
    p.add_argument("--frame", type=int, help="scene frame (default: the current one)")
    p.add_argument("--allow-shared-mounts", action="store_true",
                   help="let a set use several orientations on the same mount")
    p.add_argument("--exhaustive-limit", type=int, default=DEFAULT_EXHAUSTIVE_LIMIT,
                   help="evaluate every k-set up to this many, else greedy+swap")
    p.add_argument("--traffic", metavar="FRAMES", default=None,
                   help="also score placements with the traffic in view over these frames "
                        "(5, 1-60 or 1-60:5): visibility of the vehicles in the region")
    p.add_argument("--evaluate", metavar="FRAMES", default=None,
                   help="also judge placements by detection over these frames of the "
                        "traffic (they are traffic frames too; --traffic defaults to them): "
                        "RLS's roadside detector on each candidate and on the reported "
                        "sets (early fusion), vehicle AP_R40 at BEV IoU 0.5 in the "
                        "region, and how well InfraD, InfraNUC and visibility predict it")
    p.add_argument("--background", choices=BACKGROUNDS.ids, default="empty",
                   help="with --evaluate: the detector's background; empty (default): each "
                        "candidate's sweeps of the scene with every road user hidden, as a "
                        "deployed unit has; frames: learned from the evaluation frames, "
                        "traffic and all")
    p.add_argument("--background-sweeps", type=int, default=BACKGROUND_SWEEPS, metavar="N",
                   help=f"with --background empty: sweeps per candidate (default "
                        f"{BACKGROUND_SWEEPS})")
    p.add_argument("--evaluate-sets", type=int, default=20, metavar="N",
                   help="with --evaluate and k > 1: sets of each k scored beyond the "
                        "reported ones (drawn from those the search looked at), for the "
                        "correlation within k (default 20)")
    p.add_argument("--min-points", type=int, default=5,
                   help="with --evaluate: the returns the candidates together must put on "
                        "a box for it to count (default 5)")
    p.add_argument("--visibility-labels", default="vehicle",
                   help="labels of the objects scored for visibility (default: vehicle)")
    p.add_argument("--backend", choices=BACKENDS.ids, default="auto",
                   help="ray casting: Embree when available (auto), or Blender's BVHTree")
    p.add_argument("--overwrite", action="store_true", help="replace an existing report")
    add_cluster_arguments(p)
    p.set_defaults(func=run)


def config_from_args(args):
    from ..core.study.config import study_config

    return study_config(
        device=args.device, k=args.k, lob=args.lob, mounts=args.mount,
        grid_step=args.grid, grid_heights=args.heights, grid_margin=args.grid_margin,
        pitches=args.pitch, yaws=args.yaw, yaw_mode=args.yaw_mode, roll=args.roll,
        labels=args.labels, disks=args.disks, radius=args.radius, disk_seed=args.disk_seed,
        disk_placement=args.disk_placement, cell=args.cell, scan_seed=args.seed,
        noise=not args.no_noise, dropout=not args.no_dropout, keep_traffic=args.keep_traffic,
        backend=args.backend, frame=args.frame, one_per_mount=not args.allow_shared_mounts,
        exhaustive_limit=args.exhaustive_limit, traffic_frames=args.traffic,
        evaluate_frames=args.evaluate, evaluate_min_points=args.min_points,
        evaluate_background=args.background, background_sweeps=args.background_sweeps,
        evaluate_sets=args.evaluate_sets, rotation_hz=args.rotation_hz,
        lidar_mode=args.lidar_mode, visibility_labels=args.visibility_labels)


def _progress(done, total, cand, eta):
    say(f"[{done}/{total}] {cand.name}: {cand.n_points} points in the region "
        f"({cand.scan_points} in all) in {cand.seconds:.2f} s, about {eta:.1f} s left")


def run(args):
    cfg = config_from_args(args)
    scene = open_scene(args.blend, args.prepare_blender)
    created = not os.path.isdir(args.out)
    check_output_dir(args.out)
    try:
        return _study(args, cfg, scene)
    except BaseException:
        if created:  # a failed study leaves no empty folder behind
            try:
                os.rmdir(args.out)
            except OSError:
                pass
        raise


def _study(args, cfg, scene):
    from ..blender.study import run_study

    clash = None if args.overwrite else report_clash(args.out, cfg.k)
    if clash:
        raise SceneError(f"{clash} already exists; pass --overwrite to replace the report")
    from .distribute import scene_file, study_scan_all

    result = run_study(scene, cfg, progress=_progress,
                       scan_all=study_scan_all(args, scene_file(args)))
    for note in result.notices:
        say(f"rls: notice: {note}")
    notices = []
    summary = write_report(result, args.out, overwrite=args.overwrite, notices=notices)
    for note in notices:
        say(f"rls: notice: {note}")
    print(json.dumps(summary, indent=2))
    return 0
