"""Run the ``rls`` command line from ``blender -P`` (or any Python with ``bpy``).

    blender -b scene.blend --python-exit-code 1 -P tools/rls_entry.py -- scan --frames 1-40 --out out/scan
    blender -b --python-exit-code 1 -P tools/rls_entry.py -- study sample_scenes/t_junction.blend --k 1,2,3 --out out/study
    python tools/rls_entry.py -- presets list

Everything after the first ``--`` is handed to ``rls`` (without ``--``, all arguments
after the script are). With a scene loaded by Blender (``blender -b scene.blend``),
``scan`` and ``study`` work on that scene when their scene argument is left out.

Which ``rls_addon`` runs: the installed extension when it is enabled in this Blender
(``bl_ext.<repository>.rls_addon``), else the package in the source tree next to this
script. The process exits with rls's exit code (0, 1 for errors, 130 when interrupted).
"""

import importlib
import os
import sys

SOURCE_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def command_args(argv):
    """The arguments after the first ``--`` (all of ``argv[1:]`` when there is none)."""
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return argv[1:]


def installed_package():
    """Module name of the enabled installed extension (``bl_ext.*.rls_addon``), or None."""
    try:
        import bpy

        names = list(bpy.context.preferences.addons.keys())
    except Exception:  # no bpy, or no preferences in this session
        return None
    for name in names:
        if name.startswith("bl_ext.") and name.rsplit(".", 1)[-1] == "rls_addon":
            return name
    return None


def load_rls():
    """(the rls_addon package, where it came from)."""
    name = installed_package()
    if name is not None:
        return importlib.import_module(name), f"installed extension {name}"
    if SOURCE_ROOT not in sys.path:
        sys.path.insert(0, SOURCE_ROOT)
    return importlib.import_module("rls_addon"), f"source tree {SOURCE_ROOT}"


def main(argv=None):
    argv = sys.argv if argv is None else argv
    pkg, _ = load_rls()
    cli = importlib.import_module(pkg.__name__ + ".cli")
    return cli.main(command_args(argv), prepare_blender=pkg.ensure_registered)


if __name__ == "__main__":
    sys.exit(main())
