"""``rls dataset``: scan frames of a scene's LiDARs into a dataset layout detectors train
on, with ground-truth boxes: ``kitti`` (OpenPCDet's custom dataset) or ``opv2v``
(OPV2V/OpenCOOD). See docs/datasets.md for the frames and conventions."""

import json

from ..core.choices import BACKENDS, MOTION
from ..core.output.datasets import LAYOUTS
from ..core.errors import SceneError
from ..core.scan.background_sweeps import BACKGROUND_SWEEPS
from .distribute import add_arguments as add_cluster_arguments
from .scan import _print_step, interrupted_message, open_scene, parse_frames
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("dataset", help="scan frames into a KITTI/OpenPCDet or OPV2V dataset",
                       description=__doc__.split("\n\n", 1)[0].replace("``", "'"))
    p.add_argument("blend", nargs="?", help="scene file (omit inside 'blender -b scene.blend -c rls')")
    p.add_argument("--layout", choices=LAYOUTS.ids, required=True,
                   help="kitti: OpenPCDet's custom dataset; opv2v: OPV2V as OpenCOOD reads it")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--frames", default=None,
                   help="frame or range: 5, 1-10 or 1-10:2 (default: the current frame)")
    p.add_argument("--sensor", action="append", default=[],
                   help="LiDAR object name (repeatable; default: every LiDAR in the scene)")
    p.add_argument("--classes", default="vehicle,pedestrian,cyclist",
                   help="labels whose objects get boxes (names or ids, comma separated)")
    p.add_argument("--seed", type=int, default=None,
                   help="override each LiDAR's seed (a whole number >= 0)")
    p.add_argument("--motion", choices=MOTION.ids, default=None,
                   help="motion distortion (default: each LiDAR's setting)")
    p.add_argument("--substeps", type=int, default=None, help="sub-steps (0: adaptive)")
    p.add_argument("--backend", choices=BACKENDS.ids, default=None)
    p.add_argument("--ghosting", choices=("on", "off"), default=None)
    p.add_argument("--sweep-start", type=float, default=None, metavar="DEG",
                   help="spinning devices: azimuth where each sweep starts (degrees, "
                        "counter-clockwise from the LiDAR's +X; 180 = behind it)")
    p.add_argument("--rotation-hz", type=float, default=None, metavar="HZ",
                   help="spinning devices: the rotation rate a unit runs at (a mode of the "
                        "preset or a measured rate such as 10.017; default: each LiDAR's)")
    p.add_argument("--lidar-mode", default=None, metavar="MODE",
                   help="devices with lidar modes (Ouster): e.g. 1024x10 (default: each LiDAR's)")
    kitti = p.add_argument_group("kitti layout")
    kitti.add_argument("--intensity", choices=("0-1", "0-255"), default="0-1",
                       help="intensity scale of the points (default 0-1)")
    kitti.add_argument("--points-format", choices=("npy", "bin"), default="npy",
                       help="npy (what OpenPCDet's custom loader reads) or bin (raw float32)")
    kitti.add_argument("--level", action="store_true",
                       help="points and boxes in a gravity-aligned frame at each sensor "
                            "(its yaw kept; pitch and roll removed), as OpenPCDet assumes")
    kitti.add_argument("--min-points", type=int, default=1,
                       help="leave boxes with fewer points out of the label files (default 1)")
    kitti.add_argument("--val-share", type=float, default=0.2,
                       help="share of frames for ImageSets/val.txt, drawn with --split-seed")
    kitti.add_argument("--split-seed", type=int, default=0)
    kitti.add_argument("--val-frames", default=None,
                       help="frames A-B for validation instead of a random share")
    p.add_argument("--background-sweeps", type=int, default=BACKGROUND_SWEEPS, metavar="N",
                   help="sweeps of the scene with every road user hidden stored per still "
                        "LiDAR under background/ (what 'rls detect' learns its background "
                        f"from; default {BACKGROUND_SWEEPS}, 0: none)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files")
    p.add_argument("--resume", action="store_true",
                   help="keep complete frames of an earlier run, scan the rest")
    add_cluster_arguments(p)
    p.set_defaults(func=run)


def dataset_settings(args, current_frame):
    """The ``DatasetSettings`` of these flags (frames default to ``current_frame``)."""
    from ..core.output.datasets.settings import DatasetSettings

    val = None
    if args.val_frames:
        frames = parse_frames(args.val_frames, 0)
        val = (frames[0], frames[-1])
    return DatasetSettings(
        layout=args.layout, out=args.out, frames=parse_frames(args.frames, current_frame),
        sensors=tuple(args.sensor), classes=args.classes, seed=args.seed, motion=args.motion,
        substeps=args.substeps, backend=args.backend,
        ghosting=None if args.ghosting is None else args.ghosting == "on",
        sweep_start_deg=args.sweep_start, rotation_hz=args.rotation_hz,
        lidar_mode=args.lidar_mode, intensity=args.intensity,
        points_format=args.points_format, level=args.level, min_points=args.min_points,
        val_share=args.val_share, split_seed=args.split_seed, val_frames=val,
        background_sweeps=args.background_sweeps, overwrite=args.overwrite,
        resume=args.resume)


def dataset_run(args):
    from ..blender.dataset import dataset_run as blender_dataset_run

    if args.substeps is not None and args.substeps < 0:  # before Blender is loaded
        raise SceneError(f"--substeps must be >= 0, got {args.substeps}")
    if args.background_sweeps < 0:
        raise SceneError(f"--background-sweeps must be 0 or more, got {args.background_sweeps}")
    scene = open_scene(args.blend, args.prepare_blender)
    # a background Blender nobody edits (as rls scan's source); the frames' files written
    # behind the scan (as rls scan's clouds)
    return blender_dataset_run(scene, dataset_settings(args, scene.frame_current),
                               progress=_print_step, sweep_progress=_print_sweep,
                               edited=False, write_behind=True)


def _print_sweep(step):
    say(f"[background] {step.sensor}: a sweep of the scene without road users, "
        f"{step.points} points in {step.seconds:.2f} s")
    for w in step.warnings:
        say(f"rls: warning: {w}")


def run(args):
    from ..core.errors import interrupt_exit_code
    from ..core.scan.background_sweeps import run_all
    from .distribute import run_scan, scene_file

    job = None
    try:
        job, writer, (sweeps, hidden, sweep_notices) = dataset_run(args)
        for notice in job.notices + sweep_notices:
            say(f"rls: notice: {notice}")
        run_all(sweeps)
        # OPV2V's YAML files need every agent of a frame: pieces are whole frames.
        run_scan(args, job, scene_file(args), by_sensor=args.layout != "opv2v")
    except KeyboardInterrupt as exc:
        say(interrupted_message(job))
        return interrupt_exit_code(exc)
    for notice in writer.notices:
        say(f"rls: notice: {notice}")
    summary = job.summary()
    summary.update(layout=args.layout, dataset=str(args.out), background=None if not sweeps else {
        "sweeps": len(sweeps), "sensors": [j.name for j in sweeps[0].sensors],
        "scene_frame": sweeps[0].frames[0], "hidden_objects": len(hidden.hidden),
        "seconds": [round(s.seconds, 4) for run in sweeps for s in run.outputs],
        "what": "sweeps of the scene with every road user hidden, under background/"})
    print(json.dumps(summary, indent=2))
    return 0
