"""Operators: thin wrappers that read properties, call the Blender adapters and report
domain errors. Every operator also runs without a window (``blender -b``, the ``bpy``
module): the frame-range scan then runs straight through in ``execute()``."""

import dataclasses
import re

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from . import properties
from .blender import batch, preset_catalog
from .blender.images import image_from_png
from .blender.preview import (
    COLOR_ATTRIBUTES,
    color_preview,
    preview_object,
    preview_world_points,
)
from .blender.region import LOB_PROPERTY, is_lob, lob_polygon_world
from .blender.sensor import DEFAULT_PRESET, is_lidar, lidar_objects, lidar_props
from .core.errors import PresetError, RLSError
from .core.metrics.infra import infra_lob_metrics
from .core.points import empty_points
from .core.device.schema import ID_RE
from .core.device.presets import RangeModel
from .core.device.user_presets import (
    delete_user_preset,
    export_preset,
    import_preset,
    save_user_preset,
)
from .properties import COLOR_ITEMS, preset_items

# What the last scan operator did (for scripts and tests; reports go to the UI).
LAST_RUN = {}


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


# ---- adding objects -----------------------------------------------------------------------

class OBJECT_OT_rls_add_lidar(bpy.types.Operator):
    """Add a LiDAR sensor at the 3D cursor (its X axis looks forward, Z up)"""

    bl_idname = "object.rls_add_lidar"
    bl_label = "LiDAR"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Device", items=preset_items,
                         description="Device preset of the new LiDAR")
    show_fov: BoolProperty(name="Show Field of View", default=True,
                           description="Outline the device's field of view in the viewport")

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to add a LiDAR")
            return False
        return True

    def execute(self, context):
        obj = bpy.data.objects.new("LiDAR", None)
        obj.empty_display_type = "ARROWS"
        obj.empty_display_size = 0.5
        obj.location = context.scene.cursor.location
        (context.collection or context.scene.collection).objects.link(obj)
        s = lidar_props(obj)
        s.is_lidar = True
        s.preset_id = self.preset or DEFAULT_PRESET
        s.show_fov = self.show_fov
        _select_only(context, obj)
        return {"FINISHED"}


class OBJECT_OT_rls_add_infralob(bpy.types.Operator):
    """Add an InfraLOB: a flat rectangle on the ground marking the region the placement
    metrics (InfraD, InfraNUC) are computed over"""

    bl_idname = "object.rls_add_infralob"
    bl_label = "InfraLOB Region"
    bl_options = {"REGISTER", "UNDO"}

    size_x: FloatProperty(name="Size X", default=20.0, min=0.1, unit="LENGTH",
                          description="Length of the region along its X axis")
    size_y: FloatProperty(name="Size Y", default=30.0, min=0.1, unit="LENGTH",
                          description="Length of the region along its Y axis")

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to add a region")
            return False
        return True

    def execute(self, context):
        hx, hy = self.size_x / 2, self.size_y / 2
        mesh = bpy.data.meshes.new("InfraLOB")
        mesh.from_pydata([(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)], [], [(0, 1, 2, 3)])
        mesh.update()
        obj = bpy.data.objects.new("InfraLOB", mesh)
        obj[LOB_PROPERTY] = True
        obj.location = context.scene.cursor.location
        obj.display_type = "WIRE"
        obj.hide_render = True
        obj.visible_shadow = False
        (context.collection or context.scene.collection).objects.link(obj)
        context.scene.rls.lob = obj
        _select_only(context, obj)
        return {"FINISHED"}


# ---- scanning -------------------------------------------------------------------------------

def _report_run(op, run):
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
        op.report({"WARNING"}, f"Scan cancelled: {len(run.frames_done)} of {len(run.frames)} "
                               f"frames completed{where}")
        return {"CANCELLED"}
    if run.total == 1 and run.paths:
        where = f" to {run.paths[0]}"
    op.report({"INFO"}, f"{run.points} points from {len(run.sensors)} LiDAR(s) over "
                        f"{len(run.frames)} frame(s){where}")
    return {"FINISHED"}


class _ScanOperator:
    """What the scan operators share: they make one core scan run (``batch.make_run``)
    of ``_sensors()`` x ``_frames()``. From the UI it runs modal, a step per timer
    event, with Blender's progress bar and status text; Esc cancels after the step in
    progress (files already written stay complete; nothing half-written is left).
    Without a window (``blender -b``, scripts) it runs straight through in
    ``execute()``."""

    bl_options = {"REGISTER", "UNDO"}  # they create or replace preview objects

    write: BoolProperty(name="Write Files", default=True,
                        description="Write the point clouds and their sidecars to each "
                                    "LiDAR's output folder")
    preview: BoolProperty(name="Preview", default=True,
                          description="Show the points as an object in the scene after "
                                      "every scan")

    _timer = None
    _job = None

    def _make_run(self, context):
        return batch.make_run(context, self._sensors(context), self._frames(context),
                              write=self.write, preview=self.preview)

    def execute(self, context):
        try:
            run = self._make_run(context)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        try:
            run.run(interrupt_cancels=True)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            batch.end_run(run)
        return _report_run(self, run)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            self._job = self._make_run(context)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, self._job.total)
        self._status(context, self._job.status())
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _status(self, context, text):
        ws = getattr(context, "workspace", None)
        if ws is not None:
            try:
                ws.status_text_set(text)
            except (RuntimeError, AttributeError):
                pass

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
                self.report({"ERROR"}, str(exc))
                return {"CANCELLED"}
            except Exception:
                self._end(context)
                raise
            if job.finished:
                self._end(context)
                return _report_run(self, job)
            context.window_manager.progress_update(job.index)
            self._status(context, job.status())
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}

    def cancel(self, context):  # Blender quits or the window closes
        if self._job is not None:
            self._job.cancelled = True
            self._end(context)


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
    box says) outside the UI, over every core (``--workers auto``); needs the saved
    .blend."""
    import shlex

    sc = context.scene
    rs = sc.rls
    a, b, step = ((sc.frame_start, sc.frame_end, sc.frame_step) if rs.use_scene_range
                  else (rs.frame_start, rs.frame_end, rs.frame_step))
    frames = f"{a}-{b}" + (f":{step}" if step > 1 else "")
    parts = ["python", "-m", "rls_addon", "scan", bpy.data.filepath or "SCENE.blend",
             "--frames", frames]
    if not all_lidars:
        obj = _active_lidar(context)
        if obj is not None:
            parts += ["--sensor", obj.name]
    parts += ["--workers", "auto", "--resume"]
    return " ".join(shlex.quote(p) for p in parts)


class RLS_OT_batch_command(bpy.types.Operator):
    """Copy the command line that scans this frame range in a batch run over every core
    (or a Dask cluster with --scheduler) to the clipboard; the UI itself scans in
    Blender's own process"""

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


# ---- previews and metrics ---------------------------------------------------------------------

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
            self.report({"ERROR"}, "No preview points to colour: scan a frame first")
            return {"CANCELLED"}
        for obj in targets:
            color_preview(obj, self.attribute)
        obj = context.active_object
        if obj is not None and is_lidar(obj):
            lidar_props(obj).preview_color = self.attribute
        self.report({"INFO"}, f"Preview points coloured by {self.attribute} "
                              f"({len(targets)} object(s))")
        return {"FINISHED"}


def _find_lob(context):
    sc = context.scene
    obj = context.active_object
    if obj is not None and is_lob(obj):
        return obj
    if sc.rls.lob is not None and is_lob(sc.rls.lob) and sc.rls.lob.name in sc.objects:
        return sc.rls.lob
    lobs = [o for o in sc.objects if is_lob(o)]
    return lobs[0] if len(lobs) == 1 else None


class RLS_OT_compute_metrics(bpy.types.Operator):
    """Compute InfraD and InfraNUC over the InfraLOB from the preview points of every
    LiDAR in the scene (world frame), and make the density map image"""

    bl_idname = "rls.compute_metrics"
    bl_label = "Compute Metrics"
    bl_options = {"REGISTER", "UNDO"}  # makes the density map image

    @classmethod
    def poll(cls, context):
        if _find_lob(context) is None:
            cls.poll_message_set("Select an InfraLOB region (Add > LiDAR > InfraLOB Region) or "
                                 "choose one in the Metrics panel")
            return False
        return True

    def execute(self, context):
        sc = context.scene
        rs = sc.rls
        lob = _find_lob(context)
        clouds, names = [], []
        for obj in lidar_objects(sc):
            prev = preview_object(obj)
            if prev is None or len(prev.data.vertices) == 0:
                continue
            co, labels = preview_world_points(prev)
            pts = empty_points(len(co))
            pts["x"], pts["y"], pts["z"] = co[:, 0], co[:, 1], co[:, 2]
            pts["label"] = labels
            clouds.append(pts)
            names.append(obj.name)
        if not clouds:
            self.report({"ERROR"}, "No LiDAR points to measure: scan a frame first "
                                   "(Scan Frame or Scan All LiDARs)")
            return {"CANCELLED"}
        try:
            res = infra_lob_metrics(clouds, lob_polygon_world(lob), labels=rs.metric_labels,
                                    disks=rs.metric_disks, radius=rs.metric_radius,
                                    seed=rs.metric_seed, cell=rs.metric_cell)
        except RLSError as exc:
            self.report({"ERROR"}, f"{lob.name}: {exc}")
            return {"CANCELLED"}
        img = image_from_png(f"RLS density {lob.name}", res.density.to_png())
        rs.has_metrics = True
        rs.infra_d, rs.infra_nuc = res.infra_d, res.infra_nuc
        rs.metric_points, rs.metric_area = res.n_points, res.area_m2
        rs.metric_lob_name = lob.name
        rs.metric_sensors = ", ".join(names)
        rs.metric_image = img
        rs.lob = lob
        self.report({"INFO"}, f"{lob.name}: InfraD {res.infra_d:.3f} pts/m^2, "
                              f"InfraNUC {res.infra_nuc:.4f} ({res.n_points} points)")
        return {"FINISHED"}


# ---- presets ----------------------------------------------------------------------------------

def _preset_arg(op, context):
    pid = op.preset
    if not pid:
        obj = _active_lidar(context)
        pid = lidar_props(obj).preset_id if obj is not None else ""
    return pid


class RLS_OT_preset_apply(bpy.types.Operator):
    """Use this device preset for the active LiDAR"""

    bl_idname = "rls.preset_apply"
    bl_label = "Apply Device Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: StringProperty(name="Preset", description="Preset id")

    poll = classmethod(_poll_active_lidar)

    def execute(self, context):
        try:
            p = preset_catalog.resolve(self.preset)
        except PresetError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        s = lidar_props(_active_lidar(context))
        if p.id not in [it[0] for it in preset_items(None, None) if it]:
            properties.refresh_preset_items()  # found on disk since the list was built
        s.preset_id = p.id
        self.report({"INFO"}, f"Device: {p.name}")
        return {"FINISHED"}


def _slug(name):
    s = re.sub(r"[^a-z0-9_.-]+", "_", name.strip().lower()).strip("_.-")
    return s[:64]


class RLS_OT_preset_save(bpy.types.Operator):
    """Save the active LiDAR's device with its range and noise overrides as a user preset
    (a validated TOML file in the user preset folder)"""

    bl_idname = "rls.preset_save"
    bl_label = "Save User Preset"
    bl_options = {"REGISTER"}

    name: StringProperty(name="Name", description="Display name of the new preset")
    preset_id: StringProperty(name="Id", description="File id (default: from the name)")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace a user preset with the same id")

    poll = classmethod(_poll_active_lidar)

    def invoke(self, context, event):
        if not self.name:
            base = preset_catalog.entry(lidar_props(_active_lidar(context)).preset_id)
            self.name = f"{base.name} (custom)" if base else "My LiDAR"
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        obj = _active_lidar(context)
        s = lidar_props(obj)
        name = self.name.strip()
        if not name:
            self.report({"ERROR"}, "Give the preset a name")
            return {"CANCELLED"}
        pid = self.preset_id.strip() or _slug(name)
        if not ID_RE.match(pid):
            self.report({"ERROR"}, f"'{pid}' is not a usable preset id: lower-case letters, digits, "
                                   f"'_', '-' or '.', starting with a letter or digit")
            return {"CANCELLED"}
        try:
            base = preset_catalog.resolve(s.preset_id)
            # float32 properties: round to micrometres so 0.01 is saved as 0.01
            rng = RangeModel(
                min_m=round(s.min_range, 6) if s.use_min_range else base.range.min_m,
                max_m=round(s.max_range, 6) if s.use_max_range else base.range.max_m,
                noise_sigma_m=(round(s.noise_sigma, 6) if s.use_noise_sigma
                               else base.range.noise_sigma_m))
            source = base.source if base.id == pid else f"{base.source} [user preset based on {base.name}]"
            new = dataclasses.replace(base, id=pid, name=name, range=rng, source=source[:4000])
            path = save_user_preset(new, preset_catalog.user_dir(), overwrite=self.overwrite)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        properties.refresh_preset_items()
        s.preset_id = pid
        self.report({"INFO"}, f"Saved user preset '{pid}' to {path}")
        return {"FINISHED"}


class RLS_OT_preset_import(bpy.types.Operator):
    """Import a device preset file (.toml): it is validated, never executed, and stored
    in the user preset folder"""

    bl_idname = "rls.preset_import"
    bl_label = "Import Preset"
    bl_options = {"REGISTER"}

    filepath: StringProperty(subtype="FILE_PATH", description="The preset file to import")
    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"},
                                description="Preset files only")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace a user preset with the same id")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        if not self.filepath:
            self.report({"ERROR"}, "Choose a preset file to import")
            return {"CANCELLED"}
        try:
            p = import_preset(self.filepath, preset_catalog.user_dir(), overwrite=self.overwrite)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        properties.refresh_preset_items()
        obj = _active_lidar(context)
        if obj is not None:
            lidar_props(obj).preset_id = p.id
        self.report({"INFO"}, f"Imported preset '{p.id}' ({p.name})")
        return {"FINISHED"}


class RLS_OT_preset_export(bpy.types.Operator):
    """Export a device preset to a self-contained .toml file to share"""

    bl_idname = "rls.preset_export"
    bl_label = "Export Preset"
    bl_options = {"REGISTER"}

    filepath: StringProperty(subtype="FILE_PATH", description="Where to write the preset file")
    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"},
                                description="Preset files only")
    check_existing: BoolProperty(default=True, options={"HIDDEN"},
                                 description="Warn before replacing a file")
    preset: StringProperty(name="Preset", description="Preset id (default: the active LiDAR's)")
    overwrite: BoolProperty(name="Overwrite", default=True,
                            description="Replace an existing file")

    def invoke(self, context, event):
        pid = _preset_arg(self, context) or "preset"
        if not self.filepath:
            self.filepath = f"{pid}.toml"
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        pid = _preset_arg(self, context)
        if not pid:
            self.report({"ERROR"}, "Choose a preset to export (or select a LiDAR)")
            return {"CANCELLED"}
        try:
            path = export_preset(preset_catalog.resolve(pid), bpy.path.abspath(self.filepath),
                                 overwrite=self.overwrite)
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Exported preset '{pid}' to {path}")
        return {"FINISHED"}


class RLS_OT_preset_delete(bpy.types.Operator):
    """Delete a user preset (built-in presets are read-only)"""

    bl_idname = "rls.preset_delete"
    bl_label = "Delete User Preset"
    bl_options = {"REGISTER"}

    preset: StringProperty(name="Preset", description="Preset id (default: the active LiDAR's)")

    def invoke(self, context, event):
        return context.window_manager.invoke_confirm(
            self, event, message=f"Delete user preset '{_preset_arg(self, context)}'?")

    def execute(self, context):
        pid = _preset_arg(self, context)
        try:
            delete_user_preset(pid, preset_catalog.user_dir())
        except RLSError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        properties.refresh_preset_items()
        users = [o.name for o in bpy.data.objects if is_lidar(o) and o.rls_lidar.preset_id == pid]
        if users:
            self.report({"WARNING"}, f"LiDARs still set to the deleted preset '{pid}': "
                                     f"{', '.join(users)}; choose another device")
        self.report({"INFO"}, f"Deleted user preset '{pid}'")
        return {"FINISHED"}


class RLS_OT_preset_refresh(bpy.types.Operator):
    """Re-read the user preset folder (after copying files into it by hand)"""

    bl_idname = "rls.preset_refresh"
    bl_label = "Reload Presets"
    bl_options = {"REGISTER"}

    def execute(self, context):
        properties.refresh_preset_items()
        for err in preset_catalog.errors():
            self.report({"WARNING"}, err)
        self.report({"INFO"}, f"{len(preset_catalog.catalog())} presets; user folder "
                              f"{preset_catalog.user_dir()}")
        return {"FINISHED"}


CLASSES = (
    OBJECT_OT_rls_add_lidar,
    OBJECT_OT_rls_add_infralob,
    RLS_OT_scan_frame,
    RLS_OT_scan_all,
    RLS_OT_scan_range,
    RLS_OT_batch_command,
    RLS_OT_preview_color,
    RLS_OT_compute_metrics,
    RLS_OT_preset_apply,
    RLS_OT_preset_save,
    RLS_OT_preset_import,
    RLS_OT_preset_export,
    RLS_OT_preset_delete,
    RLS_OT_preset_refresh,
)

__all__ = ["CLASSES", "COLOR_ATTRIBUTES", "LAST_RUN"]
