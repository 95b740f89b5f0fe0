"""RLS: realistic LiDAR simulation for Blender.

This module only registers; see ``registration`` for what, and ``core`` for the
bpy-free simulation.
"""


def register():
    from . import registration

    registration.register()


def ensure_registered():
    """Register the extension where it is not yet (``python -m rls_addon``, a Dask
    worker, a factory reset): the command line's entry points hand this to the
    commands that open a scene."""
    from . import registration

    registration.ensure_registered()


def unregister():
    from . import registration

    registration.unregister()
