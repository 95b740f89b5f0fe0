"""The bpy-free core of RLS: pure functions of numpy arrays.

Nothing in this package may import ``bpy`` or ``mathutils``; collaborators that
need Blender (ray casters, scene readers) are passed in as arguments.
"""
