"""Freed frame arrays kept for the next frame (glibc's allocator, Linux).

A frame allocates some tens of arrays of 0.1-10 MB (directions, ranges, normals,
draws, point records) and frees them all at its end. glibc maps an array above its
mmap threshold with fresh pages and returns them on free, and it gives the top of its
heap back to the system above its trim threshold; both thresholds start low and rise
only after a large mapped block is freed, so how a frame's arrays fare depends on what
the process did before. When they are not kept, every page of every array is faulted
in again each frame: measured 2026-11-23 on the 2-core machine, a Pandar64 frame of the
bench's open-sky scene took 2,655 page faults and 14.5 ms; with the arrays kept,
0.4 faults and 11.0 ms (the same bytes).

``keep_freed_pages`` sets both thresholds once, to the ceiling glibc's own dynamic rule
reaches (32 MiB for mapping; twice that for trimming), as it would after freeing one
large array. What it costs: up to 64 MiB of freed memory stays with the process
instead of going back to the system, and arrays up to 32 MiB come from the heap.

Nothing is changed where the user chose: a ``MALLOC_MMAP_THRESHOLD_``,
``MALLOC_TRIM_THRESHOLD_`` or ``MALLOC_TOP_PAD_`` in the environment (glibc's own
switches), ``RLS_KEEP_FREED_PAGES=0``, or an allocator other than glibc's (Windows,
macOS, musl) leave the process as it is.
"""

import ctypes
import os
import sys

MMAP_THRESHOLD = 32 * 1024 * 1024   # glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # what glibc sets with a dynamic mmap threshold
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # malloc.h
USER_SWITCHES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")

_state = None  # None: not tried yet; else the reason string or "set"


def _glibc():
    """The process's C library when it is glibc (has ``mallopt`` and
    ``gnu_get_libc_version``), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # glibc only (musl has mallopt as a stub)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return None
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return mallopt


def keep_freed_pages(environ=None):
    """Set glibc's thresholds once per process (see the module docstring); returns
    "set", or why not. Later calls return the first call's answer."""
    global _state
    if _state is not None:
        return _state
    env = os.environ if environ is None else environ
    if env.get("RLS_KEEP_FREED_PAGES", "1") == "0":
        _state = "off: RLS_KEEP_FREED_PAGES=0"
    elif any(k in env for k in USER_SWITCHES):
        _state = "left as the environment sets it"
    else:
        mallopt = _glibc()
        if mallopt is None:
            _state = "not glibc's allocator"
        elif mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) and \
                mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD):
            _state = "set"
        else:
            _state = "glibc refused the thresholds"
    return _state
