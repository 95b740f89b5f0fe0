"""What the operators share: the active LiDAR, the InfraLOB, poll checks that say why
a button is disabled, selection, the modal loop's progress bar, status text and timer,
and ``cancelled``: a domain error reported as the operator's one error line."""

from ..blender.region import is_lob
from ..core.errors import RLSError
from ..blender.sensor import is_lidar, lidar_objects


def _active_lidar(context):
    obj = context.active_object
    return obj if obj is not None and is_lidar(obj) else None


def _poll_active_lidar(cls, context):
    if _active_lidar(context) is None:
        cls.poll_message_set("Select a LiDAR object (Add > LiDAR) first")
        return False
    return True


def _poll_any_lidar(cls, context):
    if not lidar_objects(context.scene):
        cls.poll_message_set("The scene has no LiDAR objects (Add > LiDAR)")
        return False
    return True


def find_lob(context):
    """The InfraLOB the metrics and the study work over: the active object when it is
    one, else the Metrics panel's, else the scene's only one (None: none or several)."""
    sc = context.scene
    obj = context.active_object
    if obj is not None and is_lob(obj):
        return obj
    if sc.rls.lob is not None and is_lob(sc.rls.lob) and sc.rls.lob.name in sc.objects:
        return sc.rls.lob
    lobs = [o for o in sc.objects if is_lob(o)]
    return lobs[0] if len(lobs) == 1 else None


def _poll_lob(cls, context):
    if find_lob(context) is None:
        cls.poll_message_set("Select an InfraLOB region (Add > LiDAR > InfraLOB Region) or "
                             "choose one in the Metrics panel")
        return False
    return True


def status_text(context, text):
    """Show ``text`` in the status bar (None clears it); nothing without a workspace."""
    ws = getattr(context, "workspace", None)
    if ws is not None:
        try:
            ws.status_text_set(text)
        except (RuntimeError, AttributeError):
            pass


def begin_modal(op, context, total, text):
    """Start ``op``'s modal loop: Blender's progress bar over ``total`` steps, the
    status text, and a timer event every 10 ms (a step per event)."""
    wm = context.window_manager
    wm.progress_begin(0, total)
    status_text(context, text)
    op._timer = wm.event_timer_add(0.01, window=context.window)
    wm.modal_handler_add(op)
    return {"RUNNING_MODAL"}


def end_modal(op, context):
    """End ``op``'s modal loop: its timer, the progress bar and the status text."""
    wm = context.window_manager
    if op._timer is not None:
        wm.event_timer_remove(op._timer)
        op._timer = None
    wm.progress_end()
    status_text(context, None)


def modal_step(op, context, finish, done):
    """One step of ``op._job`` in ``op``'s modal loop; returns what ``modal`` returns:
    ``finish(op, job)`` after the last step, the error as the one report line, else the
    progress bar at ``done(job)`` and the job's status text."""
    job = op._job
    try:
        if not job.finished:
            job.step()
    except RLSError as exc:
        op._end(context)
        return cancelled(op, exc)
    except Exception:
        op._end(context)
        raise
    if job.finished:
        op._end(context)
        return finish(op, job)
    context.window_manager.progress_update(done(job))
    op._status(context, job.status())
    return {"RUNNING_MODAL"}


def _select_only(context, obj):
    for o in context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj


def cancelled(op, error):
    """Report ``error`` (an ``RLSError`` or a sentence) as ``op``'s one error line and
    end it: ``return cancelled(self, exc)``."""
    op.report({"ERROR"}, str(error))
    return {"CANCELLED"}
