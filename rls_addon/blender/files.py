"""Opening and saving .blend files for the command line, with errors a user can act
on."""

import os
import shutil
import sys

import bpy

from ..core.errors import OutputError, SceneError
from ..core.output.io.atomic import place, temporary_name
from ..core.output.io.blend_file import incomplete_blend
from ..core.stop_signals import held
from .quiet import blender_output_silenced


def open_blend(path, error=SceneError):
    """Load ``path`` as the current file; raise ``error`` (an RLSError type) when it is
    missing or Blender cannot read it. Blender's own log lines stay off stdout."""
    if not os.path.isfile(path):
        raise error(f"scene file not found: {path}")
    try:
        with held(), blender_output_silenced():  # a stop signal waits for the file
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))
    except RuntimeError as exc:
        raise error(f"cannot open scene {path}: {str(exc).strip()}") from None
    warning = newer_file_warning(path, tuple(bpy.data.version), tuple(bpy.app.version_file))
    if warning:  # Blender's own "expect loss of data" went to the silenced log
        print(f"rls: warning: {warning}", file=sys.stderr)


def scene_title(scene):
    """What charts call ``scene``: its .blend file's name (``junction.blend``), with the
    scene's name when the file holds several scenes (``junction.blend, scene Night``);
    the scene's name alone for a file never saved."""
    path = bpy.data.filepath
    if not path:
        return scene.name
    name = os.path.basename(path)
    return name if len(bpy.data.scenes) == 1 else f"{name}, scene {scene.name}"


def factory_reset():
    """Blender's factory settings with an empty scene (as ``rls scene from-net`` and
    ``rls demo`` start from). Blender unregisters and registers its add-ons on the way:
    a stop signal waits for it."""
    with held():
        bpy.ops.wm.read_factory_settings(use_empty=True)


def newer_file_warning(path, file_version, app_file_version):
    """The warning for a file saved by a newer Blender than this one (None otherwise):
    Blender reads it, but data that version added is dropped or misread."""
    if tuple(file_version) <= tuple(app_file_version):
        return None
    return (f"{path} was saved by Blender {file_version[0]}.{file_version[1]} (file version "
            f"{'.'.join(map(str, file_version))}), newer than this Blender "
            f"{bpy.app.version_string}: data it added may be lost or misread; run RLS in "
            f"Blender {file_version[0]}.{file_version[1]} or later (or its bpy module)")


def save_blend(path, overwrite=False):
    """Write the current file to ``path`` all at once: a temporary in the same folder,
    checked whole (Blender's save does not always raise when the disk fills: it left a
    truncated file and returned), then a rename (without ``overwrite``, refused when
    ``path`` exists). A stop signal waits for the file to be placed or removed."""
    path = os.path.abspath(os.fspath(path))
    folder = os.path.dirname(path)
    if os.path.isdir(path):
        raise OutputError(f"cannot write {path}: it is a directory")
    if os.path.exists(path) and not overwrite:
        raise OutputError(f"{path} already exists; pass --overwrite to replace it")
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {path}: folder {folder} does not exist")
    tmp = os.path.join(folder, temporary_name(os.path.basename(path), os.urandom(6).hex()))
    with held():
        try:
            with blender_output_silenced():
                bpy.ops.wm.save_as_mainfile(filepath=tmp, compress=True, copy=True)
            if not os.path.isfile(tmp):
                raise OutputError(f"Blender did not write {path}")
            broken = incomplete_blend(tmp)
            if broken:
                raise OutputError(f"cannot write {path}: Blender's save left an incomplete "
                                  f"file ({broken}) with {_free_space(folder)}; nothing was "
                                  f"written: free some space or choose another folder")
            place(tmp, path, overwrite)
        except RuntimeError as exc:
            raise OutputError(f"cannot write {path}: {str(exc).strip()}") from None
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return path


def _free_space(folder):
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return f"an unknown free space in {folder}"
    return f"{free:,} bytes left in {folder}"
