"""Keep numpy's BLAS on one thread while a frame is scanned.

numpy's wheels (and Blender's numpy) link OpenBLAS, which runs large products
(``(N, 3) @ (3, 3)``, ``(N, 3) @ (3,)``, stacked ``inv``) on worker threads that then
spin-wait for more work for a while. On a 2-core machine those spinning threads take
the cores away from the ray caster's own threads: measured on the benchmark street, a
Pandar64 Embree cast right after such a product took 27-30 ms instead of 15 ms. The
products in a frame are small and run as fast on one thread, so the scan limits
OpenBLAS to one thread for its duration and restores the previous count afterwards.

Found through the symbols OpenBLAS exports (``openblas_get_num_threads`` /
``openblas_set_num_threads``, with the ``64_`` suffix in ILP64 builds) in the
libraries already loaded into the process; with another BLAS, or where the loaded
libraries cannot be listed, this does nothing.
"""

import ctypes
import threading
from contextlib import contextmanager

_LOCK = threading.Lock()
_HANDLES = None  # [(get, set)] for every OpenBLAS loaded, found once
_DEPTH = 0       # nested or concurrent scans: only the outermost one restores
_SAVED = []


def _loaded_openblas():
    """Paths of the OpenBLAS libraries loaded into this process (Linux)."""
    paths = []
    try:
        with open("/proc/self/maps") as f:
            for line in f:
                path = line.split(None, 5)[-1].strip()
                if "openblas" in path.lower() and path not in paths and path.startswith("/"):
                    paths.append(path)
    except OSError:
        pass
    return paths


def _handles():
    global _HANDLES
    if _HANDLES is None:
        import numpy  # noqa: F401  (loads its BLAS)

        found = []
        for path in _loaded_openblas():
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            for suffix in ("", "64_"):
                get = getattr(lib, "openblas_get_num_threads" + suffix, None)
                put = getattr(lib, "openblas_set_num_threads" + suffix, None)
                if get is not None and put is not None:
                    get.restype, get.argtypes = ctypes.c_int, []
                    put.restype, put.argtypes = None, [ctypes.c_int]
                    found.append((get, put))
                    break
        _HANDLES = found
    return _HANDLES


def threads():
    """OpenBLAS thread counts, one per library found (empty without OpenBLAS)."""
    with _LOCK:
        return [get() for get, _ in _handles()]


@contextmanager
def single_threaded():
    """Run the block with OpenBLAS on one thread (see the module docstring)."""
    global _DEPTH, _SAVED
    with _LOCK:
        handles = _handles()
        if _DEPTH == 0:
            _SAVED = [get() for get, _ in handles]
            for (_, put), n in zip(handles, _SAVED):
                if n != 1:
                    put(1)
        _DEPTH += 1
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH -= 1
            if _DEPTH == 0:
                for (get, put), n in zip(handles, _SAVED):
                    if get() != n:
                        put(n)
