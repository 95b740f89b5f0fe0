"""Choosing a ray-casting backend by name.

    factory, notice = caster_factory("auto" | "bvhtree" | "embree")

``factory(vertices, triangles)`` builds a caster (see ``core.raycast``). ``notice`` is
None, or a sentence for the user when Embree was asked for but cannot be used and
Blender's BVHTree is used instead: the fallback is never silent.
"""

from ..core import embree_caster
from .bvh_caster import BVHCaster

BACKENDS = ("auto", "bvhtree", "embree")
LABELS = {
    "auto": "Automatic (Embree when available, else BVHTree)",
    "bvhtree": "Blender BVHTree (always available)",
    "embree": "Intel Embree (bundled embreex wheel, all cores)",
}


def caster_factory(name="auto"):
    """(factory, notice or None) for backend ``name``; ValueError for an unknown name."""
    key = (name or "auto").strip().lower()
    if key not in BACKENDS:
        raise ValueError(f"unknown ray-casting backend {name!r}: choose one of "
                         + ", ".join(BACKENDS))
    if key == "bvhtree":
        return BVHCaster, None
    if embree_caster.available():
        return embree_caster.EmbreeCaster, None
    if key == "embree":
        return BVHCaster, ("Embree is not available ("
                           + embree_caster.unavailable_reason()
                           + "); scanning with Blender's BVHTree instead, which gives the "
                           "same points, more slowly")
    return BVHCaster, None


def backend_names():
    """Backends usable in this Blender: 'bvhtree' always, 'embree' when importable."""
    return ("bvhtree", "embree") if embree_caster.available() else ("bvhtree",)
