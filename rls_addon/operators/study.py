"""*Run Placement Study*: ``rls study`` from the Study panel (``bpy.ops.rls.study()``).

From the UI it runs modal (``running.ModalRun``), a step of ``blender.study_job.StudyJob``
per timer event, with Blender's progress bar and status text; Esc stops it after the
step in progress and leaves the scene as it was (nothing is made before the last step).
Without a window (``blender -b``, scripts, the ``bpy`` module) it runs straight through.
The answer is one undo step."""

import bpy

from ..blender.study_job import StudyJob, study_config
from .common import _poll_lob, find_lob
from .running import ModalRun

# What the last study did (for scripts and tests; reports go to the UI)
LAST_STUDY = {}


class RLS_OT_study(ModalRun, bpy.types.Operator):
    """Search where to mount k LiDARs over the InfraLOB, as rls study does: scan every
    candidate mount at each pitch and yaw, measure InfraD and InfraNUC (and visibility
    and detection AP when asked), and put the answer in the scene (markers, the best
    sets as LiDARs, charts, the table). Esc stops it and leaves the scene as it was"""

    bl_idname = "rls.study"
    bl_label = "Run Placement Study"
    bl_options = {"REGISTER", "UNDO"}

    poll = classmethod(_poll_lob)

    def _make_run(self, context):
        props = context.scene.rls_study
        cfg = study_config(context.scene, props, find_lob(context).name,
                           context.selected_objects)
        return StudyJob(context.scene, cfg, props.output_dir, props.overwrite)

    def _report(self, job):
        LAST_STUDY.clear()
        if job.cancelled:
            LAST_STUDY.update(cancelled=True, stage=job.stage)
            self.report({"WARNING"}, "Study stopped: nothing was added to the scene")
            return {"CANCELLED"}
        result = job.result
        best = "; ".join(f"k={k}: " + " + ".join(result.candidates[i].name
                                                 for i in s.best.members)
                         for k, s in sorted(result.searches.items()))
        text = (f"{len(result.candidates)} candidates of {result.device['name']} in "
                f"{result.timing['total_s']:.1f} s; best {best}")
        job.scene.rls_study.summary = text
        for note in job.notices:
            self.report({"WARNING"}, note)
        LAST_STUDY.update(result=result, summary=job.summary, made=job.made, cancelled=False)
        self.report({"INFO"}, text + (f"; report in {job.out_dir}" if job.out_dir else ""))
        return {"FINISHED"}


CLASSES = (
    RLS_OT_study,
)
