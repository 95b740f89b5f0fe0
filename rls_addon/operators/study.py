"""*Run Placement Study*: ``rls study`` from the Study panel (``bpy.ops.rls.study()``).

From the UI it runs modal, a step per timer event (``blender.study_job.StudyJob``),
with Blender's progress bar and status text; Esc stops it after the step in progress
and leaves the scene as it was (nothing is made before the last step). Without a
window (``blender -b``, scripts, the ``bpy`` module) it runs straight through. The
answer is one undo step."""

import bpy

from ..blender.study_job import StudyJob, study_config
from ..core.errors import RLSError
from .common import (_poll_lob, begin_modal, cancelled, end_modal, find_lob, modal_step,
                     status_text)

# What the last study did (for scripts and tests; reports go to the UI)
LAST_STUDY = {}


def _finish(op, job):
    result = job.result
    best = "; ".join(f"k={k}: " + " + ".join(result.candidates[i].name for i in s.best.members)
                     for k, s in sorted(result.searches.items()))
    text = (f"{len(result.candidates)} candidates of {result.device['name']} in "
            f"{result.timing['total_s']:.1f} s; best {best}")
    job.scene.rls_study.summary = text
    for note in job.notices:
        op.report({"WARNING"}, note)
    LAST_STUDY.clear()
    LAST_STUDY.update(result=result, summary=job.summary, made=job.made, cancelled=False)
    op.report({"INFO"}, text + (f"; report in {job.out_dir}" if job.out_dir else ""))
    return {"FINISHED"}


class RLS_OT_study(bpy.types.Operator):
    """Search where to mount k LiDARs over the InfraLOB, as rls study does: scan every
    candidate mount at each pitch and yaw, measure InfraD and InfraNUC (and visibility
    and detection AP when asked), and put the answer in the scene (markers, the best
    sets as LiDARs, charts, the table). Esc stops it and leaves the scene as it was"""

    bl_idname = "rls.study"
    bl_label = "Run Placement Study"
    bl_options = {"REGISTER", "UNDO"}

    _timer = None
    _job = None

    poll = classmethod(_poll_lob)

    def _make_job(self, context):
        props = context.scene.rls_study
        cfg = study_config(context.scene, props, find_lob(context).name,
                           context.selected_objects)
        return StudyJob(context.scene, cfg, props.output_dir, props.overwrite)

    def execute(self, context):
        try:
            job = self._make_job(context)
        except RLSError as exc:
            return cancelled(self, exc)
        try:
            job.run_all()
        except RLSError as exc:
            return cancelled(self, exc)
        finally:
            job.close()
        return _finish(self, job)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            self._job = self._make_job(context)
        except RLSError as exc:
            return cancelled(self, exc)
        return begin_modal(self, context, 1000, self._job.status())

    def _status(self, context, text):
        status_text(context, text)

    def _end(self, context):
        end_modal(self, context)
        self._job.close()

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            self._end(context)
            LAST_STUDY.clear()
            LAST_STUDY.update(cancelled=True, stage=job.stage)
            self.report({"WARNING"}, "Study stopped: nothing was added to the scene")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        return modal_step(self, context, _finish, lambda job: int(1000 * job.fraction()))

    def cancel(self, context):  # Blender quits or the window closes
        if self._job is not None:
            self._end(context)


CLASSES = (
    RLS_OT_study,
)
