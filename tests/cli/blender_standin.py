"""A stand-in for the ``blender`` program where the machine has none (the tests run
Blender as the ``bpy`` module): the two command lines RLS's docs give,

    blender -b FILE.blend -c rls ARGS...                              (extension enabled)
    blender -b [FILE.blend] --python-exit-code N -P SCRIPT.py -- ARGS...

done as Blender does them, in the order given: FILE is opened, then RLS is registered
from this source tree (as the enabled extension registers it) and the command
Blender's ``-c rls`` would call (``registration.blender_command``) gets ARGS, or SCRIPT
runs with Blender's ``sys.argv``. Any other argument is refused, so a docs line this
stand-in cannot do as Blender would fails its test instead of passing untested."""

import os
import runpy
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv):
    if not argv or argv[0] not in ("-b", "--background"):
        sys.exit(f"blender stand-in: expected -b first, got {argv[:1]}")
    rest = argv[1:]
    blend = None
    if rest and rest[0].endswith(".blend"):
        blend, rest = rest[0], rest[1:]
    import bpy

    if blend is not None:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend))
    if rest[:2] == ["-c", "rls"]:
        sys.path.insert(0, ROOT)
        import rls_addon
        from rls_addon.registration import blender_command

        rls_addon.ensure_registered()
        return blender_command(rest[2:])
    exit_code = 0
    if rest[:1] == ["--python-exit-code"]:
        exit_code, rest = int(rest[1]), rest[2:]
    if rest[:1] == ["-P"]:
        script = rest[1]
        sys.argv = ["blender", *argv]  # what a script run by Blender sees
        try:
            runpy.run_path(script, run_name="__main__")
        except SystemExit as exc:
            return int(exc.code or 0)
        except Exception:  # Blender prints the traceback and exits with the given code
            import traceback

            traceback.print_exc()
            return exit_code
        return 0
    sys.exit(f"blender stand-in: cannot do {rest} as Blender would")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
