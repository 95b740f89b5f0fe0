"""Where RLS's compiled library is: one shared library, ``_rls_native`` + the platform's
extension, in ``c/`` beside its sources (not a Python package, so nothing takes the
library for a module). It holds the Embree packet loop (``embree_loop.c``) and the
compiled stages of a frame (``points.c``, ``edges.c``, ``probes.c``, ``weather.c``,
``disks.c``, ``ghosts.c``, ``returns.c``, ``echoes.c``), each written after a numpy
reference that stays in the package. ``tools/build_native.py`` builds it for this
machine in place and cross-compiles it for every platform's zip; each entry point is
bound where it is used, after checking its interface version (``kernels.Kernel``,
``casting.embree_loop.load_native``)."""

import os
import sys

NAME = "_rls_native"


def library_name(platform=None):
    """File name of the library for ``platform`` (``sys.platform`` style; default: this
    one): ``_rls_native`` + .dll on Windows, .dylib on macOS, else .so.
    ``tools/build_native.py`` names its builds with this function."""
    plat = sys.platform if platform is None else platform
    if plat.startswith(("win", "cygwin")):
        ext = ".dll"
    elif plat == "darwin":
        ext = ".dylib"
    else:
        ext = ".so"
    return NAME + ext


def library_path():
    """Where this platform's library is looked for: ``c/`` beside this file."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "c", library_name())
