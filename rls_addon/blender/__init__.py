"""Adapters between Blender data and the bpy-free core."""
