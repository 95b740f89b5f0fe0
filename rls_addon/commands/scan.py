"""``rls scan``: scan frames of LiDAR objects in a .blend and write point clouds."""

import json
import os
import sys
import time

from ..core.errors import SceneError
from ..core.io import FORMATS

DEFAULT_TEMPLATE = "{scene}_{sensor}_{frame:06d}"


def add_parser(sub):
    p = sub.add_parser("scan", help="scan frames of LiDAR objects and write point clouds",
                       description="Scan frames of LiDAR objects and write point clouds "
                                   "with a JSON sidecar each; prints a JSON summary.")
    p.add_argument("blend", nargs="?", help="scene file (omit inside 'blender -b scene.blend -c rls')")
    p.add_argument("--sensor", action="append", default=[],
                   help="LiDAR object name (repeatable; default: every LiDAR in the scene)")
    p.add_argument("--frames", default=None,
                   help="frame or range: 5, 1-10 or 1-10:2 (default: the current frame)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--format", choices=FORMATS, default="pcd_binary")
    p.add_argument("--template", default=DEFAULT_TEMPLATE,
                   help="file name template with {scene}, {sensor}, {frame:06d}")
    p.add_argument("--seed", type=int, default=None, help="override each LiDAR's seed")
    p.add_argument("--frame-space", choices=("sensor", "world"), default=None)
    p.add_argument("--motion", choices=("exact", "substeps", "snapshot"), default=None,
                   help="motion distortion: every ray at its own time (exact), the paper's "
                        "N partial sweeps (substeps), or one state per frame (snapshot)")
    p.add_argument("--substeps", type=int, default=None,
                   help="sub-steps per frame for --motion substeps and deforming objects "
                        "(0: adaptive)")
    p.add_argument("--backend", choices=("auto", "bvhtree", "embree"), default="auto",
                   help="ray casting: Embree when available (auto), or Blender's BVHTree")
    p.add_argument("--ghosting", choices=("on", "off"), default=None,
                   help="ghost points from glossy surfaces (default: each LiDAR's setting)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files")
    p.add_argument("--resume", action="store_true",
                   help="skip scans whose cloud and sidecar already exist and agree "
                        "(the cloud reads back and has the sidecar's point count); "
                        "rescan and replace the others")
    p.set_defaults(func=run)


def apply_overrides(settings, args):
    """The LiDAR's ScanSettings with the command line's overrides applied."""
    import dataclasses

    changes = {"seed": args.seed, "frame_space": args.frame_space, "motion": args.motion,
               "substeps": args.substeps}
    if args.ghosting is not None:
        changes["ghosting"] = args.ghosting == "on"
    if args.substeps is not None and args.substeps < 0:
        raise SceneError(f"--substeps must be >= 0, got {args.substeps}")
    return dataclasses.replace(settings, **{k: v for k, v in changes.items() if v is not None})


def parse_frames(text, current):
    """'5' -> [5]; '1-10' -> 1..10; '1-10:2' -> 1,3,..,9; None -> [current]."""
    if text is None:
        return [current]
    try:
        rng, _, step = text.partition(":")
        a, sep, b = rng.partition("-")
        start, end = int(a), int(b) if sep else int(a)
        step = int(step) if step else 1
    except ValueError:
        raise SceneError(f"--frames: expected N, A-B or A-B:STEP, got '{text}'") from None
    if end < start or step < 1:
        raise SceneError(f"--frames: empty range '{text}'")
    return list(range(start, end + 1, step))


def open_scene(path):
    """Load a .blend (or keep the loaded one when path is None) and make sure the
    extension's properties are registered."""
    import bpy

    if path is not None:
        from ..blender.files import open_blend

        open_blend(path)
    if not hasattr(bpy.types.Object, "rls_lidar"):
        from .. import register

        register()
    return bpy.context.scene


def check_output_dir(path):
    """The output folder, created and writable, or an OutputError (one line)."""
    from ..core.io import writable_folder

    writable_folder(path)


def existing_output(path, sensor, frame):
    """The point count of a finished earlier output at ``path``, or None when it is
    missing or not valid: the cloud must read back, and its sidecar must exist and
    name the same sensor, frame and point count."""
    from ..core.errors import RLSError
    from ..core.io import read_cloud, read_sidecar

    if not os.path.isfile(path):
        return None
    try:
        info = read_sidecar(path)
        if not info or info.get("sensor") != sensor or info.get("frame") != frame:
            return None
        n = len(read_cloud(path))
    except (RLSError, OSError, ValueError):
        return None
    return n if info.get("points") == n else None


def _remove_orphan(path, existed):
    """After an interrupted save: drop a cloud whose sidecar was never written."""
    from ..core.io import sidecar_path

    if not existed and os.path.isfile(path) and not sidecar_path(path).exists():
        try:
            os.unlink(path)
        except OSError:
            pass


def run(args):
    try:
        return _run(args)
    except KeyboardInterrupt:
        done = _PROGRESS.get("done", 0)
        jobs = _PROGRESS.get("jobs")
        where = f" after {done} of {jobs} scans" if jobs else ""
        print(f"rls: interrupted{where}; finished files are complete, nothing partial was "
              "left; rerun with --resume to continue", file=sys.stderr)
        return 130


_PROGRESS = {}


def _run(args):
    import bpy

    from ..blender.scan import save_scan, session_for
    from ..blender.sensor import find_lidar, lidar_objects, scan_inputs
    from ..core.io import output_path

    _PROGRESS.clear()
    scene = open_scene(args.blend)
    sensors = [find_lidar(scene, n) for n in args.sensor] or lidar_objects(scene)
    if not sensors:
        raise SceneError(f"scene '{scene.name}' has no LiDAR objects (add one with Add > LiDAR)")
    frames = parse_frames(args.frames, scene.frame_current)
    check_output_dir(args.out)
    outputs, total_points, t_start = [], 0, time.perf_counter()
    session, notice = session_for(args.backend)
    if notice:
        print(f"rls: notice: {notice}", file=sys.stderr)
    jobs = len(frames) * len(sensors)
    done = scanned = resumed = 0
    scan_time = 0.0
    _PROGRESS.update(done=0, jobs=jobs)
    for frame in frames:
        frame_set = False
        for obj in sensors:
            path = output_path(args.out, args.template, scene=scene.name, sensor=obj.name,
                               frame=frame, fmt=args.format)
            if args.resume:
                n = existing_output(path, obj.name, frame)
                if n is not None:
                    done += 1
                    resumed += 1
                    _PROGRESS["done"] = done
                    total_points += n
                    outputs.append({"sensor": obj.name, "frame": frame, "points": n,
                                    "seconds": 0.0, "file": str(path), "resumed": True})
                    print(f"[{done}/{jobs}] frame {frame} {obj.name}: kept {n} points from "
                          f"an earlier run", file=sys.stderr)
                    continue
            t_job = time.perf_counter()
            if not frame_set:
                scene.frame_set(frame)
                depsgraph = bpy.context.evaluated_depsgraph_get()
                frame_set = True
            _, settings = scan_inputs(obj)
            settings = apply_overrides(settings, args)
            result, info = session.scan(depsgraph, obj, frame, settings=settings)
            existed = os.path.exists(path)
            try:
                path = save_scan(result, info, args.out, args.template, args.format, scene.name,
                                 overwrite=args.overwrite or (args.resume and existed))
            except BaseException:
                _remove_orphan(path, existed)
                raise
            done += 1
            scanned += 1
            _PROGRESS["done"] = done
            scan_time += time.perf_counter() - t_job
            total_points += len(result.points)
            outputs.append({"sensor": obj.name, "frame": frame, "points": len(result.points),
                            "seconds": round(result.seconds, 4), "file": str(path)})
            eta = scan_time / scanned * (jobs - done)
            print(f"[{done}/{jobs}] frame {frame} {obj.name}: {len(result.points)} points in "
                  f"{result.seconds:.2f} s, about {eta:.1f} s left", file=sys.stderr, flush=True)
            for w in result.warnings:
                print(f"rls: warning: {obj.name} frame {frame}: {w}", file=sys.stderr)
    summary = {"scene": scene.name, "frames": frames, "sensors": [o.name for o in sensors],
               "structure_builds": session.builds,
               "points": total_points, "seconds": round(time.perf_counter() - t_start, 3),
               "scanned": scanned, "resumed": resumed,
               "outputs": outputs}
    print(json.dumps(summary, indent=2))
    return 0
