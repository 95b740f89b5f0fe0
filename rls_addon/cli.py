"""The ``rls`` command line: one parser for ``python -m rls_addon`` and
``blender -b scene.blend -c rls``. Errors become one line on stderr and exit code 1."""

import argparse
import sys

from .commands import load_commands
from .core.errors import RLSError
from .version import VERSION


def build_parser():
    parser = argparse.ArgumentParser(
        prog="rls", description="Realistic LiDAR simulation for Blender scenes.")
    parser.add_argument("--version", action="version", version=f"rls {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for mod in load_commands():
        mod.add_parser(sub)
    return parser


def main(argv=None):
    """Run one command; return the process exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return int(exc.code or 0)
    try:
        return int(args.func(args) or 0)
    except RLSError as exc:
        print(f"rls: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("rls: interrupted: files already written are complete, none is left half-written",
              file=sys.stderr)
        return 130


def blender_command(argv):
    """Handler for ``bpy.utils.register_cli_command('rls', ...)``."""
    return main(list(argv))
