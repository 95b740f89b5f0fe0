"""Blender images made from core results (the InfraLOB density map)."""

import bpy
import numpy as np

from ..core.output.png import decode_png_rgba

IMAGE_PROPERTY = "rls_density"


def image_from_png(name, png_bytes):
    """Create or replace the image ``name`` with the pixels of ``png_bytes`` (an RGBA PNG
    as ``core.png`` writes it) and pack it, so it is saved with the .blend."""
    rgba = decode_png_rgba(png_bytes)
    h, w = rgba.shape[:2]
    img = bpy.data.images.get(name)
    if img is not None and tuple(img.size) != (w, h):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = bpy.data.images.new(name, width=w, height=h, alpha=True)
    img.alpha_mode = "STRAIGHT"
    # Blender stores rows bottom-up; the PNG's first row is the top (north).
    px = (rgba[::-1].astype(np.float32) / 255.0).ravel()
    img.pixels.foreach_set(px)
    img.update()
    img[IMAGE_PROPERTY] = True
    try:
        img.pack()
    except RuntimeError:
        pass  # unpackable in this session: the pixels stay in memory until the file closes
    try:
        img.preview_ensure()
    except (RuntimeError, AttributeError):
        pass  # no previews without a GPU context; the panel then shows a button instead
    return img
