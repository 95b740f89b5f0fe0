"""Adapters between Blender data and the bpy-free core.

Importing this package loads Blender (the ``bpy`` module) with stop signals held
(``core.stop_signals.held``): a signal that lands inside Blender's own start-up scripts
leaves Blender half started and crashed the process at exit (139). The command line
imports ``bpy`` from here (``from ..blender import bpy``) for that reason.
"""

from ..core.stop_signals import held

with held():
    import bpy  # noqa: F401
