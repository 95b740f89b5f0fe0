"""The compiled kernels of RLS's library (``library.py``) beside the Embree loop: the
per-hit stage (``points.c``), the footprint's edges and probes (``edges.c``, ``probes.c``),
the weather's false returns (``weather.c``), a study's disk counts (``disks.c``), the
ghost bounces' set-up and landing (``ghosts.c``), a static cast's returns
(``returns.c``), a footprint's echoes (``echoes.c``), the ground-truth boxes' counts
(``boxes.c``), a moving sensor's ray origins (``tracks.c``) and a sweep's moving
instances attached to their Embree scene (``instances.c``).
Each entry point is bound once, on first use, after checking its interface version;
None where the library is not built or is stale (the caller then runs its numpy
reference, which gives the same bytes)."""

import ctypes
import os
import threading

from .library import library_path
from .threads import default_threads


class Kernel:
    """One entry point ``name`` of the library, with its interface version function
    ``abi`` (returning ``version``) and its ctypes ``argtypes``."""

    def __init__(self, name, abi, version, argtypes, restype=None):
        self.name, self.abi, self.version = name, abi, version
        self.argtypes, self.restype = argtypes, restype
        self._fn, self.error = None, ""
        self._lock = threading.Lock()

    def load(self, path):
        """The entry point of the library at ``path``, bound; OSError when it is missing
        or of another interface version."""
        lib = ctypes.CDLL(path)
        try:
            abi, fn = getattr(lib, self.abi), getattr(lib, self.name)
        except AttributeError as exc:
            raise OSError(f"the compiled library has no {self.name} ({exc}); rebuild it "
                          "with tools/build_native.py") from None
        abi.restype, abi.argtypes = ctypes.c_int, []
        if abi() != self.version:
            raise OSError(f"stale {self.name} (interface {abi()}, this RLS needs "
                          f"{self.version}); rebuild it with tools/build_native.py")
        fn.restype, fn.argtypes = self.restype, self.argtypes
        return fn

    def get(self):
        """The bound function, or None (the reason in ``error``)."""
        with self._lock:
            if self._fn is None:
                path = library_path()
                try:
                    if not os.path.exists(path):
                        raise OSError(f"{os.path.basename(path)} is not built")
                    self._fn = self.load(path)
                except OSError as exc:
                    self._fn, self.error = False, str(exc)
            return self._fn or None


def threads():
    """The threads a kernel may use: the Embree loop's (the CPUs this process may run
    on, or a cluster worker's share of them, ``threads.default_threads``)."""
    return default_threads()

