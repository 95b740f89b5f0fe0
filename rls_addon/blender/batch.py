"""Scanning several frames and LiDARs from the UI: one step at a time, so a modal operator
can run it between events and a script can run it straight through.

Every output is checked before the first scan (an unusable folder fails at once, not
after ten frames); each cloud is written atomically by ``core.io``, so stopping between
steps leaves only complete files. ``request_cancel()`` stops a running job after the
step in progress (Esc in the modal operator; scripts and tests may call it, e.g. from a
frame-change handler).
"""

import os
import time

import bpy

from ..core.errors import OutputError, SceneError
from ..core.io import output_path, writable_folder
from ..core.io.fields import resolve_fields
from .preview import show_points
from .scan import save_scan, session_for
from .sensor import is_lidar, lidar_settings

_cancel = {"requested": False}


def request_cancel():
    """Ask the running scan job to stop after its current step."""
    _cancel["requested"] = True


def cancel_requested():
    return _cancel["requested"]


def resolve_output_dir(path):
    """Absolute output folder of a (possibly '//'-relative) Blender path, created and
    checked for writing; ``OutputError`` says what is wrong."""
    if not path or not path.strip():
        raise OutputError("no output folder set")
    if path.startswith("//") and not bpy.data.filepath:
        raise OutputError(f"output folder '{path}' is relative to the .blend file, which is not "
                          f"saved yet: save the file or choose an absolute folder")
    return writable_folder(os.path.normpath(bpy.path.abspath(path)))


def output_options(obj):
    """Where and how a LiDAR's clouds are written: a plain dict from its properties."""
    s = lidar_settings(obj)
    return {"dir": s.output_dir, "template": s.name_template, "format": s.file_format,
            "fields": ("x", "y", "z") + tuple(sorted(s.fields))}


def write_scan(result, info, opts, out_dir, scene_name, overwrite):
    """Write one cloud (only the chosen fields) and its sidecar; returns the cloud's path."""
    return save_scan(result, info, out_dir, opts["template"], opts["format"], scene_name,
                     overwrite=overwrite, fields=opts["fields"])


class ScanJob:
    """Frames x LiDARs to scan, one (frame, LiDAR) step per ``step()`` call."""

    def __init__(self, context, sensors, frames, write=True, preview=True, overwrite=True):
        if not sensors:
            raise SceneError(f"scene '{context.scene.name}' has no LiDAR objects "
                             f"(add one with Add > LiDAR)")
        if not frames:
            raise SceneError("no frames to scan (the frame range is empty)")
        self.context = context
        self.scene = context.scene
        self.names = [o.name for o in sensors]
        self.frames = list(frames)
        self.write, self.preview, self.overwrite = write, preview, overwrite
        self.steps = [(f, n) for f in self.frames for n in self.names]
        self.outputs = {}
        if write:  # fail before scanning anything
            for obj in sensors:
                opts = output_options(obj)
                out = resolve_output_dir(opts["dir"])
                output_path(out, opts["template"], scene=self.scene.name, sensor=obj.name,
                            frame=self.frames[0], fmt=opts["format"])
                resolve_fields(list(opts["fields"]))
                self.outputs[obj.name] = (opts, out)
        backend = getattr(lidar_settings(sensors[0]), "backend", "auto")
        self.session, notice = session_for(backend.lower())
        self.original_frame = self.scene.frame_current
        self.index = 0
        self.paths, self.warnings = [], [notice] if notice else []
        self.points = 0
        self.frames_done = []
        self.cancelled = False
        self.t0 = time.perf_counter()
        _cancel["requested"] = False

    @property
    def total(self):
        return len(self.steps)

    @property
    def finished(self):
        return self.cancelled or self.index >= len(self.steps)

    def status(self):
        f, n = self.steps[min(self.index, len(self.steps) - 1)]
        elapsed = time.perf_counter() - self.t0
        left = elapsed / self.index * (self.total - self.index) if self.index else 0.0
        return (f"LiDAR scan: frame {f} ({n}), {self.index}/{self.total} done, "
                f"about {left:.0f} s left (Esc to cancel)")

    def step(self):
        """Scan the next (frame, LiDAR); returns False when nothing is left or a cancel
        was requested before the step began."""
        if self.finished:
            return False
        frame, name = self.steps[self.index]
        if self.scene.frame_current != frame:
            self.scene.frame_set(frame)
        if _cancel["requested"]:  # e.g. asked for by a frame-change handler
            self.cancelled = True
            return False
        obj = self.scene.objects.get(name)
        if obj is None or not is_lidar(obj):
            raise SceneError(f"LiDAR '{name}' was removed while scanning")
        result, info = self.session.scan(self.context.evaluated_depsgraph_get(), obj, frame)
        if self.write:
            opts, out = self.outputs[name]
            self.paths.append(write_scan(result, info, opts, out, self.scene.name, self.overwrite))
        if self.preview:
            show_points(self.scene, obj, result.points, info["frame_space"],
                        info["sensor_to_world"], color_by=lidar_settings(obj).preview_color)
        self.points += len(result.points)
        self.warnings += [f"{name} frame {frame}: {w}" for w in result.warnings]
        self.index += 1
        if self.index == len(self.steps) or self.steps[self.index][0] != frame:
            self.frames_done.append(frame)
        self.last = (result, info)
        return not self.finished

    def run(self):
        """Run every step (background mode, scripts). Ctrl+C counts as a cancel."""
        try:
            while self.step():
                pass
        except KeyboardInterrupt:
            self.cancelled = True
        finally:
            self.finish()
        return self

    def finish(self):
        _cancel["requested"] = False
        if self.scene.frame_current != self.original_frame:
            self.scene.frame_set(self.original_frame)
