"""What operators that run a core ``ScanRun`` share (the scan operators, the dataset
export): the modal loop with Blender's progress bar, status text and Esc, and the
report of a run that ended (``LAST_RUN`` for scripts and tests)."""

import bpy

from ..blender import batch
from ..core.errors import RLSError
from .common import cancelled, status_text


# What the last run of an operator did (for scripts and tests; reports go to the UI).
LAST_RUN = {}


def report_run(op, run, what="Scan", later=None):
    """The reports of a run that ended; ``later``: what a cancelled run that wrote files
    leaves unwritten, said after the cancel (default: its writer's run-level files,
    ``written_at_end``)."""
    for w in run.warnings[:5]:
        op.report({"WARNING"}, w)
    if len(run.warnings) > 5:
        op.report({"WARNING"}, f"... and {len(run.warnings) - 5} more warnings")
    LAST_RUN.clear()
    LAST_RUN.update(cancelled=run.cancelled, frames_done=list(run.frames_done),
                    frames=list(run.frames), steps_done=run.index, steps=run.total,
                    paths=[str(p) for p in run.paths], points=run.points,
                    warnings=list(run.warnings))
    where = f", {len(run.paths)} files written" if run.writer is not None else ""
    if run.cancelled:
        op.report({"WARNING"}, f"{what} cancelled: {len(run.frames_done)} of {len(run.frames)} "
                               f"frames completed{where}")
        files = getattr(run.writer, "written_at_end", None)  # none for a bag
        if files and run.paths:
            op.report({"INFO"}, later or f"{files[0].upper()}{files[1:]} written once every "
                                         "frame is done")
        return {"CANCELLED"}
    if run.total == 1 and run.paths:
        where = f" to {run.paths[0]}"
    op.report({"INFO"}, f"{run.points} points from {len(run.sensors)} LiDAR(s) over "
                        f"{len(run.frames)} frame(s){where}")
    return {"FINISHED"}


class ModalRun:
    """Operators that drive one core ``ScanRun`` (``_make_run(context)``): from the UI
    modal, a step per timer event, with Blender's progress bar and status text; Esc
    cancels after the step in progress (files already written stay complete; nothing
    half-written is left). Without a window (``blender -b``, scripts) straight through
    in ``execute()``. An operator that opens a file browser first has a hidden
    ``from_ui`` property that its ``invoke`` sets: Blender then calls ``execute``, which
    goes modal too."""

    _timer = None
    _job = None

    def _make_run(self, context):
        raise NotImplementedError

    def _report(self, run):
        """The operator's result and reports once the run ended (``report_run``)."""
        return report_run(self, run)

    def _windowed(self, context):
        return not bpy.app.background and context.window is not None

    def execute(self, context):
        if getattr(self, "from_ui", False) and self._windowed(context):
            return self._start(context)
        try:
            run = self._make_run(context)
        except RLSError as exc:
            return cancelled(self, exc)
        try:
            run.run(interrupt_cancels=True)
        except RLSError as exc:
            return cancelled(self, exc)
        finally:
            batch.end_run(run)
        return self._report(run)

    def invoke(self, context, event):
        if not self._windowed(context):
            return self.execute(context)
        return self._start(context)

    def _start(self, context):
        try:
            self._job = self._make_run(context)
        except RLSError as exc:
            return cancelled(self, exc)
        wm = context.window_manager
        wm.progress_begin(0, self._job.total)
        self._status(context, self._job.status())
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _status(self, context, text):
        status_text(context, text)

    def _end(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        self._status(context, None)
        batch.end_run(self._job)

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            batch.request_cancel()
            job.cancelled = True
        if event.type == "TIMER" or job.cancelled:
            try:
                if not job.finished:
                    job.step()
            except RLSError as exc:
                self._end(context)
                return cancelled(self, exc)
            except Exception:
                self._end(context)
                raise
            if job.finished:
                self._end(context)
                return self._report(job)
            context.window_manager.progress_update(job.index)
            self._status(context, job.status())
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}

    def cancel(self, context):  # Blender quits or the window closes
        if self._job is not None:
            self._job.cancelled = True
            self._end(context)
