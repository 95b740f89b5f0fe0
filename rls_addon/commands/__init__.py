"""Command-line subcommands. Each module defines ``add_parser(subparsers)``, which
registers its parser and sets ``func`` to a ``run(args) -> int`` callable."""

import importlib

# Module names under this package, in the order ``--help`` lists them.
COMMAND_MODULES = ("scan", "lidar", "dataset", "study", "demo", "presets", "pattern", "metrics",
                   "detect", "evaluate", "scene", "traffic")


def load_commands():
    """Import the command modules that exist (later issues add more)."""
    mods = []
    for name in COMMAND_MODULES:
        try:
            mods.append(importlib.import_module(f"{__package__}.{name}"))
        except ModuleNotFoundError as exc:
            if exc.name != f"{__package__}.{name}":
                raise
    return mods
