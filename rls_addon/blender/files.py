"""Opening .blend files for the command line, with errors a user can act on."""

import os

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
