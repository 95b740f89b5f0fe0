"""RLS: realistic LiDAR simulation for Blender.

This module only registers; see ``registration`` for what, and ``core`` for the
bpy-free simulation.
"""


def register():
    from . import registration

    registration.register()


def unregister():
    from . import registration

    registration.unregister()
