"""*Live Coverage* on and off, and *Update Coverage* (on demand): ``blender.live``."""

import bpy

from ..blender import live
from ..blender.sensor import lidar_objects
from ..core.errors import RLSError
from .common import _poll_lob, cancelled, find_lob


class RLS_OT_live_coverage(bpy.types.Operator):
    """Live coverage on or off: while on, a LiDAR that is moved, turned, retargeted or
    given another preset (or another frame) is rescanned once it is still, and its
    preview, the InfraLOB's InfraD and InfraNUC and the coverage map follow"""

    bl_idname = "rls.live_coverage"
    bl_label = "Live Coverage"
    bl_options = {"REGISTER"}

    poll = classmethod(_poll_lob)

    def execute(self, context):
        sc = context.scene
        if live.is_live(sc):
            live.stop()
            sc.rls_live.status = "off"
            self.report({"INFO"}, "Live coverage off")
            return {"FINISHED"}
        if not lidar_objects(sc):
            return cancelled(self, "The scene has no LiDAR objects (Add > LiDAR)")
        lob = find_lob(context)
        props = sc.rls_live
        try:
            live.start(sc, lob, props.debounce_ms, props.budget_ms)
        except RLSError as exc:
            return cancelled(self, exc)
        self.report({"INFO"}, f"Live coverage of {lob.name}: InfraD {props.infra_d:.3f} "
                              f"points/m², InfraNUC {props.infra_nuc:.4f}")
        return {"FINISHED"}


class RLS_OT_live_update(bpy.types.Operator):
    """Rescan the LiDARs that changed (with none changed: every LiDAR, after an edit
    live coverage does not follow, such as a material or a visibility) and update the
    coverage now (a scene too heavy to follow live is updated this way), and go back to
    following live"""

    bl_idname = "rls.live_update"
    bl_label = "Update Coverage"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if not live.is_live(context.scene):
            cls.poll_message_set("Turn Live Coverage on first")
            return False
        return True

    def execute(self, context):
        try:
            live.update_now()
        except RLSError as exc:
            return cancelled(self, exc)
        return {"FINISHED"}


CLASSES = (
    RLS_OT_live_coverage,
    RLS_OT_live_update,
)
