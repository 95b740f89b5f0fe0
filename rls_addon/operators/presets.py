"""The device-preset operators behind the LiDAR panel's preset menu: apply, save as a
user preset, import, export, delete, reload. Presets are validated TOML data, never
code."""

import dataclasses
import re
from pathlib import PurePath

import bpy
from bpy.props import BoolProperty, StringProperty

from .. import properties
from ..blender import preset_catalog
from ..blender.sensor import is_lidar, lidar_props
from ..core.errors import PresetError, RLSError
from ..core.device.schema import ID_RE
from ..core.device.presets import RangeModel
from ..core.device.user_presets import (
    delete_user_preset,
    export_preset,
    import_preset,
    save_user_preset,
)
from ..properties import preset_items
from .common import _active_lidar, _poll_active_lidar, cancelled


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
            return cancelled(self, exc)
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
            return cancelled(self, "Give the preset a name")
        pid = self.preset_id.strip() or _slug(name)
        if not ID_RE.match(pid):
            return cancelled(self, f"'{pid}' is not a usable preset id: lower-case letters, "
                                   "digits, '_', '-' or '.', starting with a letter or digit")
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
            return cancelled(self, exc)
        properties.refresh_preset_items()
        s.preset_id = pid
        self.report({"INFO"}, f"Saved user preset '{pid}' to {path}")
        return {"FINISHED"}


def _use_new_preset(context, preset):
    """After an import: the preset lists re-read, and the active LiDAR (if any) on it."""
    properties.refresh_preset_items()
    obj = _active_lidar(context)
    if obj is not None:
        lidar_props(obj).preset_id = preset.id


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
            return cancelled(self, "Choose a preset file to import")
        try:
            p = import_preset(self.filepath, preset_catalog.user_dir(), overwrite=self.overwrite)
        except RLSError as exc:
            return cancelled(self, exc)
        _use_new_preset(context, p)
        self.report({"INFO"}, f"Imported preset '{p.id}' ({p.name})")
        return {"FINISHED"}


class RLS_OT_preset_import_calibration(bpy.types.Operator):
    """Import a unit's calibration file (Hesai angle-correction CSV, Velodyne YAML or
    db.xml, Ouster metadata JSON, RoboSense angle.csv) as a user preset built on a preset
    of the same model: the unit's angles and beam origins, everything else the base's"""

    bl_idname = "rls.preset_import_calibration"
    bl_label = "Import Calibration"
    bl_options = {"REGISTER"}

    filepath: StringProperty(subtype="FILE_PATH", description="The unit's calibration file")
    filter_glob: StringProperty(default="*.csv;*.yaml;*.yml;*.xml;*.json", options={"HIDDEN"},
                                description="Calibration files")
    base: StringProperty(name="Base Preset",
                         description="Preset of the same model to build on (default: the "
                                     "active LiDAR's)")
    preset_id: StringProperty(name="Id", description="Id of the new preset (default: from "
                                                     "the base and the file name)")
    name: StringProperty(name="Name", description="Display name (default: the base's name "
                                                  "and the file name)")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace a user preset with the same id")

    def invoke(self, context, event):
        if not self.base:
            obj = _active_lidar(context)
            if obj is not None:
                self.base = lidar_props(obj).preset_id
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..core.device.calibration_import import import_calibration

        if not self.filepath:
            return cancelled(self, "Choose a calibration file to import")
        base = self.base.strip()
        if not base:
            obj = _active_lidar(context)
            base = lidar_props(obj).preset_id if obj is not None else ""
        if not base:
            return cancelled(self, "Choose the base preset (a preset of the same model)")
        path = bpy.path.abspath(self.filepath)
        stem = PurePath(path.replace("\\", "/")).stem
        pid = self.preset_id.strip() or _slug(f"{base}_{stem}")
        try:
            p = import_calibration(path, preset_catalog.resolve(base), pid,
                                   preset_catalog.user_dir(), name=self.name.strip() or None,
                                   overwrite=self.overwrite)
        except RLSError as exc:
            return cancelled(self, exc)
        _use_new_preset(context, p)
        self.report({"INFO"}, f"Imported calibration as preset '{p.id}' ({p.name})")
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
            return cancelled(self, "Choose a preset to export (or select a LiDAR)")
        try:
            path = export_preset(preset_catalog.resolve(pid), bpy.path.abspath(self.filepath),
                                 overwrite=self.overwrite)
        except RLSError as exc:
            return cancelled(self, exc)
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
            return cancelled(self, exc)
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
    RLS_OT_preset_apply,
    RLS_OT_preset_save,
    RLS_OT_preset_import,
    RLS_OT_preset_import_calibration,
    RLS_OT_preset_export,
    RLS_OT_preset_delete,
    RLS_OT_preset_refresh,
)
