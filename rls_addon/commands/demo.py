"""``rls demo``: build the sample intersection with its traffic, put a LiDAR on a
traffic-light pole looking into the junction, scan one frame, and run a small
placement study on the sample T-junction."""

import json
import os
import time

from .scan import check_output_dir

DEMO_SCENE = "intersection"  # with its LiDAR (scenes.SAMPLE_LIDARS): on the pole TL SW
DEMO_FRAME = 24           # its first four cars are near the junction then


def add_parser(sub):
    p = sub.add_parser("demo", help="scan the bundled sample intersection once",
                       description="Generate the sample intersection (roads, buildings, a "
                                   "glass facade, traffic), mount a LiDAR on a "
                                   "traffic-light pole, scan one frame, write the point cloud "
                                   "and its picture, and run a small placement study.")
    p.add_argument("--out", default="out/demo", help="output directory (default: out/demo)")
    p.add_argument("--device", default="hesai_pandar64",
                   help="device preset id or name (default: hesai_pandar64)")
    p.add_argument("--no-study", action="store_true",
                   help="skip the placement study on the sample T-junction")
    p.set_defaults(func=run)


def run(args):
    from ..blender import bpy  # loaded with stop signals held
    from ..blender.files import factory_reset
    from ..blender.quiet import blender_output_silenced
    from ..blender.scenes import SAMPLE_LIDARS, add_sample_lidar, build_scene
    from ..blender.sensor import read_settings, sensor_job
    from ..blender.source import BlenderScene
    from ..core.casting import backend_status
    from ..core.device.presets import get_preset
    from ..core.output.io.writer import make_writer, picture_path
    from ..core.scan.run import ScanRun

    preset = get_preset(args.device)
    check_output_dir(args.out)
    factory_reset()
    args.prepare_blender()
    scene = bpy.context.scene
    build_scene(DEMO_SCENE, scene)
    lidar = add_sample_lidar(DEMO_SCENE, scene, preset=preset.id)  # the sample scene's
    mount = SAMPLE_LIDARS[DEMO_SCENE].mount
    blend = os.path.abspath(os.path.join(args.out, f"{DEMO_SCENE}.blend"))
    scene.frame_set(DEMO_FRAME)
    t0 = time.perf_counter()
    # The same run as 'rls scan' and the UI's operators, into --out.
    job = sensor_job(lidar, read_settings(lidar).override(directory=os.path.abspath(args.out)))
    backend, why = backend_status(job.settings.backend)
    source = BlenderScene(scene)
    preview = _has_matplotlib()
    writer = make_writer([job], scene.name, source.fps, source.frame_start, overwrite=True,
                         preview=preview)
    run = ScanRun(source, [job], [DEMO_FRAME], writer=writer).run()
    result, _ = run.last
    path = run.paths[0]
    seconds = time.perf_counter() - t0
    with blender_output_silenced():
        bpy.ops.wm.save_as_mainfile(filepath=blend)
    summary = {"device": preset.name, "points": len(result.points), "rays": result.rays,
               "triangles": result.triangles, "seconds": round(seconds, 3),
               "frame": DEMO_FRAME, "mount": mount, "backend": backend,
               "backend_why": why, "point_cloud": str(os.path.abspath(path)), "scene": blend,
               "picture": str(os.path.abspath(picture_path(path))) if preview else None}
    if not args.no_study:
        summary["study"] = run_demo_study(args.out, preset.id, args.prepare_blender)
    print(json.dumps(summary, indent=2))
    print(f"Scanned {summary['points']} points ({preset.name} on the pole '{mount}', "
          f"{result.rays} rays, frame {DEMO_FRAME}) in {seconds:.2f} s.\n"
          f"Ray casting: {why}.\nPoint cloud: {summary['point_cloud']}\nScene: {blend}")
    print(f"Picture of the cloud: {summary['picture']}" if preview else
          "No picture of the cloud: matplotlib is not installed (pip install matplotlib)")
    if "study" in summary:
        st = summary["study"]
        best = st["best"][str(max(DEMO_K))]
        print(f"Placement study ({st['candidates']} candidates on the T-junction, "
              f"{st['seconds']:.1f} s): best {max(DEMO_K)} sensors "
              f"{', '.join(best['sensors'])}: InfraD {best['infra_d']:.1f} points/m^2, "
              f"InfraNUC {best['infra_nuc']:.3f}.\nStudy report: {st['report']}")
    return 0


DEMO_K = (1, 2, 3)


def _has_matplotlib():
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def run_demo_study(out_dir, device, prepare_blender):
    """The paper's scenario A in small: the sample T-junction, its five corner and
    bar-side mounts, 1 to 3 sensors; report under ``out_dir/study``."""
    from ..blender import bpy
    from ..blender.files import factory_reset
    from ..blender.quiet import blender_output_silenced
    from ..blender.scenes import build_scene
    from ..blender.study import run_study
    from ..core.study.config import StudyConfig
    from ..core.study.report import write_report

    factory_reset()
    prepare_blender()
    build_scene("t_junction", bpy.context.scene)
    study_dir = os.path.join(out_dir, "study")
    check_output_dir(study_dir)
    cfg = StudyConfig(device=device, k=DEMO_K,
                      mounts=("TL NE", "TL NW", "TL SE", "TL SW", "SL S"))
    result = run_study(bpy.context.scene, cfg)
    with blender_output_silenced():
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(os.path.join(study_dir,
                                                                          "t_junction.blend")))
    return write_report(result, study_dir, overwrite=True)
