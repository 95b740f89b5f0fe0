"""``rls dataset``: scan frames of a scene's LiDARs into a dataset layout detectors train
on, with ground-truth boxes: ``kitti`` (OpenPCDet's custom dataset) or ``opv2v``
(OPV2V/OpenCOOD). See docs/datasets.md for the frames and conventions."""

import json
import sys

from ..core.choices import BACKENDS, MOTION
from ..core.output.datasets import LAYOUTS
from ..core.errors import SceneError
from .distribute import add_arguments as add_cluster_arguments
from .scan import _print_step, interrupted_at, open_scene, parse_frames


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
    p.add_argument("--overwrite", action="store_true", help="replace existing files")
    p.add_argument("--resume", action="store_true",
                   help="keep complete frames of an earlier run, scan the rest")
    add_cluster_arguments(p)
    p.set_defaults(func=run)


def carrier_of(obj, classes):
    """The object a LiDAR rides on, when it is an object of ``classes`` (its parent, or
    a parent's parent): that vehicle is the LiDAR's OPV2V agent."""
    from ..blender.labels import object_label

    o = obj.parent
    while o is not None:
        if object_label(o) in classes:
            return o.name
        o = o.parent
    return None


def dataset_writer(args, scene, sensors, classes):
    from ..core.output.datasets.common import Split
    from ..core.output.datasets.kitti import KittiWriter
    from ..core.output.datasets.opv2v import Opv2vWriter, agents_for

    if args.layout == "kitti":
        val = None
        if args.val_frames:
            frames = parse_frames(args.val_frames, 0)
            val = (frames[0], frames[-1])
        return KittiWriter(args.out, scene.name,
                           intensity_scale=255.0 if args.intensity == "0-255" else 1.0,
                           points_format=args.points_format, level=args.level,
                           min_points=args.min_points,
                           split=Split(args.val_share, args.split_seed, val),
                           overwrite=args.overwrite, resume=args.resume, background=True)
    carriers = {o.name: carrier_of(o, classes) for o in sensors}
    return Opv2vWriter(args.out, scene.name, agents_for([o.name for o in sensors], carriers),
                       {k: v for k, v in carriers.items() if v}, overwrite=args.overwrite,
                       resume=args.resume)


def dataset_run(args):
    from ..blender.sensor import find_lidar, lidar_objects, read_settings, sensor_job
    from ..blender.source import BlenderScene
    from ..core.labels import label_ids, label_name
    from ..core.scan.run import ScanRun

    scene = open_scene(args.blend, args.prepare_blender)
    sensors = [find_lidar(scene, n) for n in args.sensor] or lidar_objects(scene)
    if not sensors:
        raise SceneError(f"scene '{scene.name}' has no LiDAR objects (add one with Add > LiDAR)")
    if args.substeps is not None and args.substeps < 0:
        raise SceneError(f"--substeps must be >= 0, got {args.substeps}")
    classes = label_ids(args.classes)
    changes = {"seed": args.seed, "motion": args.motion, "substeps": args.substeps,
               "backend": args.backend, "frame_space": "sensor", "ground_truth": True,
               "object_classes": tuple(label_name(c) for c in classes),
               "ghosting": None if args.ghosting is None else args.ghosting == "on",
               "sweep_start_deg": args.sweep_start, "rotation_hz": args.rotation_hz,
               "lidar_mode": args.lidar_mode}
    jobs = [sensor_job(o, read_settings(o).override(**changes)) for o in sensors]
    writer = dataset_writer(args, scene, sensors, set(classes))
    frames = parse_frames(args.frames, scene.frame_current)
    # a background Blender: nobody edits the file (as rls scan's source)
    return (ScanRun(BlenderScene(scene, edited=False), jobs, frames, writer=writer,
                    progress=_print_step), writer)


def run(args):
    from ..core.errors import interrupt_exit_code
    from .distribute import run_scan, scene_file

    job = None
    try:
        job, writer = dataset_run(args)
        for notice in job.notices:
            print(f"rls: notice: {notice}", file=sys.stderr)
        # OPV2V's YAML files need every agent of a frame: pieces are whole frames.
        run_scan(args, job, scene_file(args), by_sensor=args.layout != "opv2v")
    except KeyboardInterrupt as exc:
        print(f"rls: interrupted{interrupted_at(job)}; finished files are complete, nothing "
              "partial was left; rerun with --resume to continue", file=sys.stderr)
        return interrupt_exit_code(exc)
    for notice in writer.notices:
        print(f"rls: notice: {notice}", file=sys.stderr)
    summary = job.summary()
    summary.update(layout=args.layout, dataset=str(args.out))
    print(json.dumps(summary, indent=2))
    return 0
