"""What the operators share: the active LiDAR, poll checks that say why a button is
disabled, selection, ``cancelled``: a domain error reported as the operator's one
error line, and ``status_text``: the status bar's text while one works."""



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


def status_text(context, text):
    """Show ``text`` in the status bar (None clears it); nothing without a window."""
    ws = getattr(context, "workspace", None)
    if ws is not None:
        try:
            ws.status_text_set(text)
        except (RuntimeError, AttributeError):
            pass
