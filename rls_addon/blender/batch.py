"""Scan runs from the UI: the core's ``ScanRun`` over this Blender scene, with the
LiDARs' own output settings and viewport previews.

Every output is checked before the first scan (an unusable folder fails at once, not
after ten frames); each cloud is written atomically, so stopping between steps leaves
only complete files. ``request_cancel()`` stops a running scan after the step in
progress (Esc in the modal operators; scripts and tests may call it, e.g. from a
frame-change handler).
"""

from ..core.errors import OutputError, OutputExists
from ..core.output.io.writer import make_writer
from ..core.scan.run import ScanRun
from .preview import show_points
from .sensor import absolute_output, lidar_props, read_settings, sensor_job
from .source import BlenderScene

_cancel = {"requested": False}


def request_cancel():
    """Ask the running scan to stop after its current step."""
    _cancel["requested"] = True


def cancel_requested():
    return _cancel["requested"]


def clear_cancel():
    """A new run starts with no cancel asked for."""
    _cancel["requested"] = False


def make_run(context, sensors, frames, write=True, preview=True, overwrite=False):
    """A ``ScanRun`` of LiDAR objects ``sensors`` over ``frames`` of the context's scene:
    files as each LiDAR's Output panel says (when ``write``), previews shown after each
    scan (when ``preview``). A file the run would write that exists already is refused
    before anything is scanned, as ``rls scan`` refuses it, unless ``overwrite``."""
    scene = context.scene
    jobs = []
    for obj in sensors:
        settings = read_settings(obj)
        if write:
            settings = absolute_output(settings)
        jobs.append(sensor_job(obj, settings))

    def show(job, frame, result, info):
        obj = scene.objects.get(job.name)
        if obj is not None:
            show_points(scene, obj, result.points, info["frame_space"], info["sensor_to_world"],
                        color_by=lidar_props(obj).preview_color)

    clear_cancel()
    source = BlenderScene(scene, context)
    writer = make_writer(jobs, scene.name, source.fps, source.frame_start,
                         overwrite=overwrite) if write else None
    try:
        return ScanRun(source, jobs, frames, writer=writer, on_result=show if preview else None,
                       cancelled=cancel_requested)
    except OutputExists as exc:
        n = len(exc.paths)
        raise OutputError(f"{exc.paths[0]} already exists"
                          + (f" (and {n - 1} more)" if n > 1 else "")
                          + ": tick Overwrite Files to replace, or choose another output "
                            "folder or file names in the LiDAR's Output panel") from None


def end_run(run):
    """Put the scene back at its frame and clear a cancel request (the next run starts
    clean)."""
    clear_cancel()
    run.finish()
