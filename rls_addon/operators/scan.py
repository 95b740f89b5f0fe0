"""Operators that scan: *Scan Frame*, *Scan All LiDARs* and *Scan Frame Range* (modal
from the UI with Blender's progress bar and status text, Esc cancels; straight through
without a window), the equivalent command line, and the preview's colouring."""

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty

from ..blender import batch
from ..blender.preview import color_preview, preview_object
from ..blender.sensor import is_lidar, lidar_objects, lidar_props
from ..core.errors import RLSError
from ..properties import COLOR_ITEMS
from .common import _active_lidar, _poll_active_lidar, _poll_any_lidar, cancelled
from .running import LAST_RUN, ModalRun


class _ScanOperator(ModalRun):
    """What the scan operators share: they make one core scan run (``batch.make_run``)
    of ``_sensors()`` x ``_frames()``, modal from the UI (``ModalRun``)."""

    bl_options = {"REGISTER", "UNDO"}  # they create or replace preview objects

    write: BoolProperty(name="Write Files", default=True,
                        description="Write the point clouds and their sidecars to each "
                                    "LiDAR's output folder")
    preview: BoolProperty(name="Preview", default=True,
                          description="Show the points as an object in the scene after "
                                      "every scan")
    overwrite: BoolProperty(name="Overwrite Files", default=False,
                            description="Replace files of earlier scans; without it a file "
                                        "that exists is refused before anything is scanned, "
                                        "as rls scan refuses it")

    def _make_run(self, context):
        return batch.make_run(context, self._sensors(context), self._frames(context),
                              write=self.write, preview=self.preview, overwrite=self.overwrite)


class RLS_OT_scan_frame(_ScanOperator, bpy.types.Operator):
    """Scan the current frame with the active LiDAR, write the cloud and show the points"""

    bl_idname = "rls.scan_frame"
    bl_label = "Scan Frame"

    poll = classmethod(_poll_active_lidar)

    def _sensors(self, context):
        return [_active_lidar(context)]

    def _frames(self, context):
        return [context.scene.frame_current]


class RLS_OT_scan_all(_ScanOperator, bpy.types.Operator):
    """Scan the current frame with every LiDAR in the scene"""

    bl_idname = "rls.scan_all"
    bl_label = "Scan All LiDARs"

    poll = classmethod(_poll_any_lidar)

    def _sensors(self, context):
        return lidar_objects(context.scene)

    def _frames(self, context):
        return [context.scene.frame_current]


class RLS_OT_scan_range(_ScanOperator, bpy.types.Operator):
    """Scan a range of frames and write a cloud per frame and LiDAR. Runs in the
    background of the UI with a progress bar; Esc cancels after the frame in progress
    (files already written stay complete; nothing half-written is left)"""

    bl_idname = "rls.scan_range"
    bl_label = "Scan Frame Range"

    all_lidars: BoolProperty(name="All LiDARs", default=False,
                             description="Scan with every LiDAR in the scene, not only the active one")
    use_scene_range: BoolProperty(name="Scene Frame Range", default=True,
                                  description="Scan the scene's frame range (else Start to End)")
    frame_start: IntProperty(name="Start", default=1, description="First frame to scan")
    frame_end: IntProperty(name="End", default=1, description="Last frame to scan")
    frame_step: IntProperty(name="Step", default=1, min=1, description="Scan every Nth frame")

    poll = classmethod(_poll_any_lidar)

    def _sensors(self, context):
        if self.all_lidars:
            return lidar_objects(context.scene)
        obj = _active_lidar(context)
        if obj is None:
            raise RLSError("select a LiDAR object, or enable 'All LiDARs'")
        return [obj]

    def _frames(self, context):
        sc = context.scene
        if self.use_scene_range:
            a, b, step = sc.frame_start, sc.frame_end, sc.frame_step
        else:
            a, b, step = self.frame_start, self.frame_end, self.frame_step
        if b < a:
            raise RLSError(f"empty frame range {a}-{b}")
        return list(range(a, b + 1, max(1, step)))


def batch_command(context, all_lidars=True):
    """The command line that scans this scene's frame range (as the Scan Frame Range
    box says) outside the UI: this Blender run in the background on the saved .blend,
    with the installed extension's ``rls`` command (``blender -b FILE -c rls scan``),
    which a user who installed the zip can run as it is. ``--resume`` keeps frames a
    stopped run finished."""
    import shlex

    sc = context.scene
    rs = sc.rls
    a, b, step = ((sc.frame_start, sc.frame_end, sc.frame_step) if rs.use_scene_range
                  else (rs.frame_start, rs.frame_end, rs.frame_step))
    frames = f"{a}-{b}" + (f":{step}" if step > 1 else "")
    parts = [bpy.app.binary_path or "blender", "-b", bpy.data.filepath or "SCENE.blend",
             "-c", "rls", "scan", "--frames", frames]
    if not all_lidars:
        obj = _active_lidar(context)
        if obj is not None:
            parts += ["--sensor", obj.name]
    parts += ["--resume"]
    return " ".join(shlex.quote(p) for p in parts)


class RLS_OT_batch_command(bpy.types.Operator):
    """Copy the command line that scans this frame range with Blender in the background
    (blender -b FILE -c rls scan ...) to the clipboard, to run outside the UI"""

    bl_idname = "rls.batch_command"
    bl_label = "Copy Batch Command"
    bl_options = {"REGISTER"}

    all_lidars: BoolProperty(name="All LiDARs", default=True,
                             description="Every LiDAR in the scene, not only the active one")

    def execute(self, context):
        text = batch_command(context, self.all_lidars)
        context.window_manager.clipboard = text  # (no clipboard without a window)
        LAST_RUN["batch_command"] = text
        if not bpy.data.filepath:
            self.report({"WARNING"}, "Save the .blend first: the batch run reads the scene "
                                     "from its file")
        self.report({"INFO"}, text)
        return {"FINISHED"}


def _previews(context, everything):
    if everything:
        objs = [preview_object(o) for o in lidar_objects(context.scene)]
        return [o for o in objs if o is not None]
    obj = context.active_object
    if obj is not None and obj.get("rls_preview"):
        return [obj]
    if obj is not None and is_lidar(obj):
        p = preview_object(obj)
        return [p] if p is not None else []
    return []


class RLS_OT_preview_color(bpy.types.Operator):
    """Colour the preview points by a point attribute (shown in Material Preview and
    Rendered shading; the points are drawn by a geometry-nodes modifier)"""

    bl_idname = "rls.preview_color"
    bl_label = "Color Preview Points"
    bl_options = {"REGISTER", "UNDO"}

    attribute: EnumProperty(name="Color By", items=COLOR_ITEMS, default="intensity",
                            description="Point attribute the preview is coloured by")
    all_previews: BoolProperty(name="All LiDARs", default=False,
                               description="Colour the previews of every LiDAR in the scene")

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or not (is_lidar(obj) or obj.get("rls_preview")):
            cls.poll_message_set("Select a LiDAR or its preview points")
            return False
        return True

    def execute(self, context):
        targets = _previews(context, self.all_previews)
        if not targets:
            return cancelled(self, "No preview points to colour: scan a frame first")
        for obj in targets:
            color_preview(obj, self.attribute)
        obj = context.active_object
        if obj is not None and is_lidar(obj):
            lidar_props(obj).preview_color = self.attribute
        self.report({"INFO"}, f"Preview points coloured by {self.attribute} "
                              f"({len(targets)} object(s))")
        return {"FINISHED"}


CLASSES = (
    RLS_OT_scan_frame,
    RLS_OT_scan_all,
    RLS_OT_scan_range,
    RLS_OT_batch_command,
    RLS_OT_preview_color,
)
