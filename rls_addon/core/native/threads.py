"""How many threads the compiled library may use: the CPUs this process may run on, or
``RLS_THREADS`` when set (a worker of a local Dask cluster gets its share of the
cores). ``RLS_EMBREE_THREADS``, the name before the library held more than the Embree
loop, is still read, with a notice, when ``RLS_THREADS`` is not set."""

import os
import sys

ENV = "RLS_THREADS"
OLD_ENV = "RLS_EMBREE_THREADS"
_NOTICED = []


def default_threads():
    """The threads the Embree loop and the compiled stages use (at least 1)."""
    forced = os.environ.get(ENV, "").strip()
    if not forced:
        forced = os.environ.get(OLD_ENV, "").strip()
        if forced and not _NOTICED:
            _NOTICED.append(True)
            print(f"rls: notice: {OLD_ENV} is now called {ENV}; the old name still works "
                  "for now", file=sys.stderr)
    if forced.isdigit() and int(forced) > 0:
        return int(forced)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)
