"""Blender images made from core results (density maps, study charts): the PNG bytes
the core draws, packed into the .blend and decoded by Blender itself, so any PNG
(matplotlib's charts or RLS's own bare maps) shows as it was drawn."""

import bpy

IMAGE_PROPERTY = "rls_density"


def image_from_png(name, png_bytes, tag=IMAGE_PROPERTY):
    """Create or replace the image ``name`` holding ``png_bytes`` (a whole PNG file),
    packed, so it is saved with the .blend; ``tag`` is set as a custom property on it
    (what made it)."""
    old = bpy.data.images.get(name)
    if old is not None:
        bpy.data.images.remove(old)
    img = bpy.data.images.new(name, width=8, height=8, alpha=True)
    img.pack(data=png_bytes, data_len=len(png_bytes))
    img.source = "FILE"  # decoded from the packed PNG: its own size and pixels
    img.alpha_mode = "STRAIGHT"
    img[tag] = True
    try:
        img.preview_ensure()
    except (RuntimeError, AttributeError):
        pass  # no previews without a GPU context; the panel then shows a button instead
    return img
