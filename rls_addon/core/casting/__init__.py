"""The ray-casting backends, and choosing one by name.

    factory, notice = caster_factory("auto" | "bvhtree" | "embree" | "open3d" | "numpy")
    backend, why = backend_status("auto")     # what a LiDAR set to "auto" will use, and why

``factory`` is a backend class (see ``base``: what every backend must do and may do).
``notice`` is None, or a sentence for the user when Embree was asked for but cannot
be used and another backend is used instead: the fallback is never silent. The
choices users see are ``choices.BACKENDS``; "auto" and "embree" take, in this order,
Embree 4 from the ``embreex`` wheel (bundled in the Linux and Windows zips; packets,
the compiled loop), Embree 4 from the ``pyemblite`` wheel (bundled in the macOS zips;
one core), Open3D's ``RaycastingScene`` (Embree inside; where a user has Open3D),
Blender's BVHTree (docs/platforms.md). "open3d" by name and "numpy" (brute force) are
for tests and benchmarks.
"""

import functools

from ..choices import BACKENDS
from ..errors import SettingsError
from ..native.threads import default_threads
from . import embree, embree_api, embree_loop, emblite
from .base import GRAZING, Caster, CasterBase, cast_exact, refine_hits, triangle_planes
from .bvhtree import BVHCaster
from .embree import EmbreeCaster
from .emblite import EmbliteCaster
from . import open3d_caster
from .numpy_caster import NumpyCaster
from .open3d_caster import Open3DCaster
from .watertight import WatertightCaster


def caster_factory(name="auto"):
    """(factory, notice or None) for backend ``name``; ``SettingsError`` for an
    unknown name."""
    key = (name or "auto").strip().lower()
    if key == "numpy":
        return NumpyCaster, None
    if key == "open3d":
        if open3d_caster.available():
            return Open3DCaster, None
        return BVHCaster, ("Open3D is not available (" + open3d_caster.unavailable_reason()
                           + "); scanning with Blender's BVHTree instead, which gives the "
                           "same points, more slowly")
    if key not in BACKENDS:
        raise SettingsError(f"unknown ray-casting backend {name!r}; choose one of "
                            + ", ".join(BACKENDS.ids))
    if key == "bvhtree":
        return BVHCaster, None
    if embree.available():
        return embree.EmbreeCaster, None
    if emblite.available():
        return EmbliteCaster, None
    if open3d_caster.available():
        if key == "embree":
            return Open3DCaster, ("Embree's embreex and pyemblite wheels are not available ("
                                  + embree.unavailable_reason() + "); scanning with the "
                                  "Embree inside Open3D's RaycastingScene instead, which "
                                  "gives the same points")
        return Open3DCaster, None
    if key == "embree":
        return BVHCaster, ("Embree is not available (" + embree.unavailable_reason()
                           + "); scanning with Blender's BVHTree instead, which gives the "
                           "same points, more slowly")
    return BVHCaster, None


def backend_names():
    """Backends usable here: 'bvhtree' always, 'embree' (embreex or pyemblite) and
    'open3d' when importable."""
    return ("bvhtree",) + (("embree",) if embree.available() or emblite.available() else ()) \
        + (("open3d",) if open3d_caster.available() else ())


@functools.lru_cache(maxsize=None)
def backend_status(name="auto"):
    """(backend id, reason sentence): the backend a LiDAR set to ``name`` will cast
    with here and why, e.g. ("bvhtree", "BVHTree: no Embree build for this platform
    (ModuleNotFoundError: No module named 'embreex')"). Worked out once per name and
    process (it imports the backends, as the first scan would): cheap enough to ask
    from a panel's ``draw``. ``backend_status.cache_clear()`` forgets the answers."""
    try:
        factory, _ = caster_factory(name)
    except SettingsError as exc:
        return "bvhtree", f"BVHTree: {exc}"
    if factory is NumpyCaster:
        return "numpy", "numpy: brute force, exact (tests and tiny scenes)"
    if factory is EmbliteCaster:
        return "embree", ("Embree 4 from the pyemblite wheel, one ray at a time on one core "
                          "(no embreex wheel for this platform)")
    if factory is Open3DCaster:
        why = ("no Embree wheel for this platform"
               if not (embree.available() or emblite.available()) else "as chosen")
        return "open3d", f"Open3D: Embree inside Open3D's RaycastingScene, all cores ({why})"
    if factory is embree.EmbreeCaster:
        threads = default_threads()
        cores = f"{threads} core{'s' if threads != 1 else ''}"
        if embree_api._packet_library() is None:  # e.g. an embreex on Embree 2 or 3
            return "embree", ("Embree: embreex's own ray loop, one core (packets need "
                              "Embree 4: " + embree.packet_mode_error() + ")")
        if embree_loop._native_loop() is None:
            return "embree", (f"Embree: packets from Python on {cores}, slower ("
                              + embree_loop.native_loop_error() + ")")
        return "embree", f"Embree with the compiled loop on {cores}"
    if (name or "auto").strip().lower() == "bvhtree":
        return "bvhtree", "BVHTree: as chosen (one core)"
    return "bvhtree", ("BVHTree: no Embree build for this platform ("
                       + embree.unavailable_reason() + "); one core")


__all__ = ["BVHCaster", "Caster", "CasterBase", "EmbliteCaster", "EmbreeCaster", "GRAZING",
           "NumpyCaster", "Open3DCaster", "WatertightCaster", "backend_names", "backend_status",
           "cast_exact", "caster_factory", "refine_hits", "triangle_planes"]
