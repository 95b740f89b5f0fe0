"""Opening .blend files for the command line, with errors a user can act on."""

import os
import sys

import bpy

from ..core.errors import SceneError
from .quiet import blender_output_silenced


def open_blend(path, error=SceneError):
    """Load ``path`` as the current file; raise ``error`` (an RLSError type) when it is
    missing or Blender cannot read it. Blender's own log lines stay off stdout."""
    if not os.path.isfile(path):
        raise error(f"scene file not found: {path}")
    try:
        with blender_output_silenced():
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))
    except RuntimeError as exc:
        raise error(f"cannot open scene {path}: {str(exc).strip()}") from None
    warning = newer_file_warning(path, tuple(bpy.data.version), tuple(bpy.app.version_file))
    if warning:  # Blender's own "expect loss of data" went to the silenced log
        print(f"rls: warning: {warning}", file=sys.stderr)


def newer_file_warning(path, file_version, app_file_version):
    """The warning for a file saved by a newer Blender than this one (None otherwise):
    Blender reads it, but data that version added is dropped or misread."""
    if tuple(file_version) <= tuple(app_file_version):
        return None
    return (f"{path} was saved by Blender {file_version[0]}.{file_version[1]} (file version "
            f"{'.'.join(map(str, file_version))}), newer than this Blender "
            f"{bpy.app.version_string}: data it added may be lost or misread; run RLS in "
            f"Blender {file_version[0]}.{file_version[1]} or later (or its bpy module)")
