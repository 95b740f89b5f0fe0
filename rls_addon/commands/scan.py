"""``rls scan``: scan frames of LiDAR objects in a .blend and write point clouds.

Each LiDAR is scanned and written as its own panels say (device, range, motion,
Output: folder, format, fields, frame, file names); a flag overrides that setting for
every LiDAR of the run."""

import json

from ..core.choices import (
    BACKENDS,
    DETECTION,
    FIELDS,
    FOOTPRINT,
    FRAME_SPACES,
    MOTION,
    RETURN_MODES,
)
from ..core.errors import SceneError
from ..core.output.io.formats import FORMATS
from ..core.output.io.point_types import POINT_TYPES
from ..core.scan.frames import parse_frames
from .distribute import add_arguments as add_cluster_arguments
from .stderr import say


def add_parser(sub):
    p = sub.add_parser("scan", help="scan frames of LiDAR objects and write point clouds",
                       description="Scan frames of LiDAR objects and write point clouds "
                                   "with a JSON sidecar each; prints a JSON summary. Every "
                                   "setting left out comes from each LiDAR's own panels.")
    p.add_argument("blend", nargs="?", help="scene file (omit inside 'blender -b scene.blend -c rls')")
    p.add_argument("--sensor", action="append", default=[],
                   help="LiDAR object name (repeatable; default: every LiDAR in the scene)")
    p.add_argument("--frames", default=None,
                   help="frame or range: 5, 1-10 or 1-10:2 (default: the current frame)")
    p.add_argument("--out", default=None,
                   help="output folder (default: each LiDAR's own, '//' being the .blend's folder)")
    p.add_argument("--format", choices=FORMATS.ids, default=None,
                   help="cloud format (default: each LiDAR's)")
    p.add_argument("--fields", default=None,
                   help="comma-separated point fields besides x,y,z: "
                        + ",".join(FIELDS.ids) + " (default: each LiDAR's)")
    p.add_argument("--template", default=None,
                   help="file name template with {scene}, {sensor}, {frame:06d} "
                        "(default: each LiDAR's)")
    p.add_argument("--seed", type=int, default=None,
                   help="override each LiDAR's seed (a whole number >= 0)")
    p.add_argument("--frame-space", choices=FRAME_SPACES.ids, default=None,
                   help="point coordinates in the sensor or world frame (default: each LiDAR's)")
    p.add_argument("--motion", choices=MOTION.ids, default=None,
                   help="motion distortion: every ray at its own time (exact), the paper's "
                        "N partial sweeps (substeps), or one state per frame (snapshot)")
    p.add_argument("--substeps", type=int, default=None,
                   help="sub-steps per frame for --motion substeps and deforming objects "
                        "(0: chosen from how far things move)")
    p.add_argument("--backend", choices=BACKENDS.ids, default=None,
                   help="ray casting: Embree when available (auto), or Blender's BVHTree "
                        "(default: each LiDAR's)")
    p.add_argument("--ghosting", choices=("on", "off"), default=None,
                   help="ghost points from glossy surfaces (default: each LiDAR's setting)")
    p.add_argument("--point-type", choices=POINT_TYPES, default=None,
                   help="PCD, PLY and bags: the fields of a LiDAR driver's ROS point "
                        "(velodyne, ouster, hesai, autoware) or RLS's own (rls, default: "
                        "each LiDAR's); see docs/formats.md")
    p.add_argument("--start-time", type=float, default=None, metavar="SECONDS",
                   help="absolute time of the scene's first frame (e.g. Unix seconds) for "
                        "bag stamps, LAS GPS times, Hesai timestamps and sidecars (default 0)")
    p.add_argument("--crs", default=None, metavar="EPSG:CODE",
                   help="LAS: the coordinate reference system of the world frame")
    p.add_argument("--las-offset", default=None, metavar="X,Y,Z",
                   help="LAS: world offset in metres (default: per file, whole km)")
    p.add_argument("--preview-png", action="store_true",
                   help="also write a picture of each cloud (bird's-eye and perspective "
                        "views by label, intensity) beside it (needs matplotlib)")
    p.add_argument("--sweep-start", type=float, default=None, metavar="DEG",
                   help="spinning devices: azimuth where each sweep starts (degrees, "
                        "counter-clockwise from the LiDAR's +X; 180 = behind it)")
    p.add_argument("--weather", default=None, metavar="SPEC",
                   help="fog, rain or snow: 'fog:visibility=50' (m), 'rain:rate=10' (mm/h), "
                        "'snow:rate=2[,type=wet]' (mm/h water equivalent), or 'clear' "
                        "(default: each LiDAR's); see docs/realism.md")
    p.add_argument("--detection", choices=DETECTION.ids, default=None,
                   help="what is detected: the LiDAR equation from the preset's datasheet "
                        "figures where it has them (auto), or CARLA's model for every "
                        "preset (carla) (default: each LiDAR's)")
    p.add_argument("--footprint", choices=FOOTPRINT.ids, default=None,
                   help="beam footprints: a beam is a cone of the preset's divergence, "
                        "sampled near depth edges into multiple returns and mixed points "
                        "(auto; presets without a divergence keep thin rays), or thin rays "
                        "always (off) (default: each LiDAR's); see docs/realism.md")
    p.add_argument("--return-mode", choices=RETURN_MODES.ids, default=None,
                   help="which echoes of a pulse are reported: the device's (preset), the "
                        "strongest, the last, or both (dual) (default: each LiDAR's)")
    p.add_argument("--rotation-hz", type=float, default=None, metavar="HZ",
                   help="spinning devices: the rotation rate a unit runs at, a mode of the "
                        "preset or a measured rate such as 10.017 (checked against the "
                        "device's modes; default: each LiDAR's)")
    p.add_argument("--lidar-mode", default=None, metavar="MODE",
                   help="devices with lidar modes (Ouster): e.g. 1024x10, 2048x10 (rls presets "
                        "show NAME lists them; default: each LiDAR's)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files")
    p.add_argument("--resume", action="store_true",
                   help="skip scans whose cloud and sidecar already exist and agree "
                        "(the cloud reads back and has the sidecar's point count); "
                        "rescan and replace the others")
    add_cluster_arguments(p)
    p.set_defaults(func=run)


def overrides(args):
    """The command line's changes to each LiDAR's settings (None: not given)."""
    if args.substeps is not None and args.substeps < 0:
        raise SceneError(f"--substeps must be >= 0, got {args.substeps}")
    fields = None
    if args.fields is not None:
        fields = ("x", "y", "z") + tuple(f.strip() for f in args.fields.split(",") if f.strip())
    return {"seed": args.seed, "frame_space": args.frame_space, "motion": args.motion,
            "substeps": args.substeps, "backend": args.backend, "format": args.format,
            "fields": fields, "template": args.template, "directory": args.out,
            "sweep_start_deg": args.sweep_start, "point_type": args.point_type,
            "start_time_s": args.start_time, "crs": args.crs,
            "las_offset": _offset(args.las_offset), "weather": _weather(args.weather),
            "detection": args.detection, "footprint": args.footprint,
            "return_mode": args.return_mode,
            "rotation_hz": getattr(args, "rotation_hz", None),
            "lidar_mode": getattr(args, "lidar_mode", None),
            "ghosting": None if args.ghosting is None else args.ghosting == "on"}


def _weather(text):
    """The --weather spec, validated ('clear' clears each LiDAR's weather)."""
    if text is None:
        return None
    from ..core.errors import SettingsError
    from ..core.physics.weather import parse_weather

    try:
        air = parse_weather(text)
    except SettingsError as exc:
        raise SceneError(f"--weather: {exc}") from None
    return "clear" if air is None else air.spec


def _offset(text):
    if text is None:
        return None
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3:
        raise SceneError(f"--las-offset: expected X,Y,Z in metres, got '{text}'")
    return vals


def open_scene(path, prepare_blender):
    """Load a .blend (or keep the loaded one when path is None) and make sure the
    extension is registered (``prepare_blender``, from the entry point). A stop signal
    waits for Blender to be loaded (``core.stop_signals.held``)."""
    from ..core.stop_signals import held

    with held():
        from ..blender import bpy

        if path is not None:
            from ..blender.files import open_blend

            open_blend(path)
        prepare_blender()
    return bpy.context.scene


def check_output_dir(path):
    """The output folder, created and writable, or an OutputError (one line)."""
    from ..core.output.io import writable_folder

    writable_folder(path)


def step_time(step):
    """'0.28 s wall (frame 0.05, scene 0.14, scan 0.06, write 0.03)': the step's wall
    time and what it went on (a step run on a worker says only its scan's)."""
    if not step.parts:
        return f"{step.seconds:.2f} s (the scan)"
    return (f"{step.wall_s:.2f} s wall ("
            + ", ".join(f"{k} {v:.2f}" for k, v in step.parts.items()) + ")")


def _print_step(step):
    if step.resumed:
        say(f"[{step.done}/{step.total}] frame {step.frame} {step.sensor}: kept {step.points} "
            f"points from an earlier run")
        return
    say(f"[{step.done}/{step.total}] frame {step.frame} {step.sensor}: {step.points} points "
        f"in {step_time(step)}, about {step.eta_s:.1f} s left")
    for w in step.warnings:
        say(f"rls: warning: {w}")


def scan_run(args):
    """The core's ``ScanRun`` for these arguments: the scene opened, every LiDAR's
    settings read and overridden, outputs checked."""
    from ..blender.sensor import (
        absolute_output,
        find_lidar,
        lidar_objects,
        read_settings,
        sensor_job,
    )
    from ..blender.source import BlenderScene
    from ..core.output.io.writer import make_writer
    from ..core.scan.run import ScanRun

    scene = open_scene(args.blend, args.prepare_blender)
    sensors = [find_lidar(scene, n) for n in args.sensor] or lidar_objects(scene)
    if not sensors:
        raise SceneError(f"scene '{scene.name}' has no LiDAR objects (add one with Add > LiDAR)")
    changes = overrides(args)
    if changes["format"] is not None and changes["frame_space"] is None:
        # a format whose clouds are in one frame (bags: the sensor's) sets it
        changes["frame_space"] = FORMATS.get(changes["format"]).frame_space
    jobs, folders = [], {}
    for obj in sensors:
        settings = read_settings(obj).override(**changes)
        if args.out is None:
            own = settings.output.directory
            settings = absolute_output(settings)
            folders.setdefault((settings.output.directory, own), []).append(obj.name)
        jobs.append(sensor_job(obj, settings))
    for (folder, own), names in folders.items():  # no --out: say where the files go
        say(f"rls: notice: no --out given: {', '.join(names)} write{'s' if len(names) == 1 else ''} "
            f"to {folder} (the Output folder '{own}' of the LiDAR panel)")
    frames = parse_frames(args.frames, scene.frame_current)
    source = BlenderScene(scene, edited=False)  # a background Blender: nobody edits it
    writer = make_writer(jobs, scene.name, source.fps, source.frame_start,
                         overwrite=args.overwrite, resume=args.resume, preview=args.preview_png,
                         background=True)
    return ScanRun(source, jobs, frames, writer=writer, progress=_print_step)


def interrupted_at(job):
    """' after N of M scans' for the message of a stopped run: the scans whose files are
    complete (on workers, more than the pieces this process heard back from)."""
    if job is None:
        return ""
    done = job.index
    if job.writer is not None and not job.finished:
        try:
            done = max(done, job.complete_on_disk())
        except OSError:
            pass
    return f" after {done} of {job.total} scans"


def interrupted_message(job):
    """The one line of a stopped run: what is on disk and how to go on. A run that
    writes one file for all its scans (a ROS 2 bag) leaves none and cannot be resumed."""
    if job is not None and getattr(job.writer, "per_scan", True) is False:
        return (f"rls: interrupted{interrupted_at(job)}; a ROS 2 bag is written whole when "
                "its run ends, so none was left (a bag cannot be resumed): run it again")
    later = getattr(job.writer, "written_at_end", None) if job is not None else None
    return (f"rls: interrupted{interrupted_at(job)}; finished files are complete, nothing "
            f"partial was left; rerun with --resume to continue"
            + (f" ({later} written once every scan is done)" if later else ""))


def run(args):
    from ..core.errors import interrupt_exit_code
    from .distribute import run_scan, scene_file

    job = None
    try:
        job = scan_run(args)
        for notice in job.notices:
            say(f"rls: notice: {notice}")
        run_scan(args, job, scene_file(args))
    except KeyboardInterrupt as exc:
        say(interrupted_message(job))
        return interrupt_exit_code(exc)
    print(json.dumps(job.summary(), indent=2))
    return 0
