"""Stop signals held over the few steps that must not be cut in the middle.

The command line turns SIGTERM and SIGHUP into ``Interrupted`` where they arrive, as
Ctrl-C does (``cli``). A few steps cannot take an exception from any line: importing
Blender and registering its add-ons (an exception there crashed the process), starting
a Dask cluster (half-started nannies left tracebacks behind). Within ``held()`` a stop
signal is noted, and raised as ``Interrupted`` when the step ends.
"""

import contextlib
import threading

from .errors import Interrupted

_state = {"held": 0, "pending": None}


@contextlib.contextmanager
def held():
    """Hold stop signals until the block ends (nested blocks: the outermost). Only the
    main thread takes signals, so elsewhere (a background write) this holds nothing and
    can never raise a signal there."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _state["held"] += 1
    try:
        yield
    finally:
        _state["held"] -= 1
        pending = _state["pending"]
        if not _state["held"] and pending is not None:
            _state["pending"] = None
            raise Interrupted(pending)


def deliver(signum):
    """What the command line's handler does with stop signal ``signum``: raise it now,
    or note it for the end of a ``held()`` block."""
    if _state["held"]:
        if _state["pending"] is None:
            _state["pending"] = int(signum)
        return
    raise Interrupted(signum)
