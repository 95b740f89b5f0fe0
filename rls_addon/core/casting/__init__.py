"""The ray-casting backends, and choosing one by name.

    factory, notice = caster_factory("auto" | "bvhtree" | "embree" | "numpy")

``factory`` is a backend class (see ``base``: what every backend must do and may do).
``notice`` is None, or a sentence for the user when Embree was asked for but cannot
be used and Blender's BVHTree is used instead: the fallback is never silent. The
choices users see are ``choices.BACKENDS``; "numpy" (brute force) is for tests and
tiny scenes.
"""

from ..choices import BACKENDS
from ..errors import SettingsError
from . import embree
from .base import GRAZING, Caster, CasterBase, cast_exact, refine_hits, triangle_planes
from .bvhtree import BVHCaster
from .embree import EmbreeCaster
from .numpy_caster import NumpyCaster
from .watertight import WatertightCaster


def caster_factory(name="auto"):
    """(factory, notice or None) for backend ``name``; ``SettingsError`` for an
    unknown name."""
    key = (name or "auto").strip().lower()
    if key == "numpy":
        return NumpyCaster, None
    if key not in BACKENDS:
        raise SettingsError(f"unknown ray-casting backend {name!r}; choose one of "
                            + ", ".join(BACKENDS.ids))
    if key == "bvhtree":
        return BVHCaster, None
    if embree.available():
        return embree.EmbreeCaster, None
    if key == "embree":
        return BVHCaster, ("Embree is not available (" + embree.unavailable_reason()
                           + "); scanning with Blender's BVHTree instead, which gives the "
                           "same points, more slowly")
    return BVHCaster, None


def backend_names():
    """Backends usable here: 'bvhtree' always, 'embree' when importable."""
    return ("bvhtree", "embree") if embree.available() else ("bvhtree",)


__all__ = ["BVHCaster", "Caster", "CasterBase", "EmbreeCaster", "GRAZING", "NumpyCaster", "WatertightCaster",
           "backend_names", "cast_exact", "caster_factory", "refine_hits", "triangle_planes"]
