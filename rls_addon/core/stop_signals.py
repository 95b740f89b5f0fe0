"""Stop signals held over the few steps that must not be cut in the middle.

The command line turns SIGINT (Ctrl-C), SIGTERM and SIGHUP into ``Interrupted`` where
they arrive (``cli``). A few steps cannot take an exception from any line: importing
Blender, resetting it and registering its add-ons (an exception there left Blender half
started and crashed the process at exit: 139), starting a Dask cluster (half-started
nannies left tracebacks behind). Within ``held()`` a stop signal is noted, and raised as
``Interrupted`` when the step ends.

Before the command line takes the signals over, ``python -m rls_addon`` notes them from
its first line (``note_from_start``) and ``cli.main`` raises a noted one where the
command starts (``raise_noted``), so a stop during the imports ends like a stop later.
Only Python's own start comes before that first line (about 30 ms on this project's
machine): there the signal's default action ends the process. Once the command has
ended, stop signals are ignored while Python shuts down (``ignore_after_end``).
"""

import contextlib
import signal
import threading

from .errors import Interrupted

_state = {"held": 0, "pending": None, "raised": None}
STOP_SIGNAL_NAMES = ("SIGINT", "SIGTERM", "SIGHUP")


def stop_signals():
    """The stop signals this platform has (Windows has no SIGHUP)."""
    return tuple(getattr(signal, n) for n in STOP_SIGNAL_NAMES if hasattr(signal, n))


def _note(signum, frame):
    if _state["pending"] is None:
        _state["pending"] = int(signum)


def note_from_start():
    """For an entry point's first line: from now on a stop signal is noted, never
    raised (Python's own Ctrl-C would raise in whatever import is under way), until the
    command line installs its own handlers; ``raise_noted`` raises it there."""
    for s in stop_signals():
        signal.signal(s, _note)


def ignore_after_end():
    """For an entry point's last line, once the command has ended (its files complete,
    its exit code decided): stop signals are ignored while Python shuts down. Python
    resets handlers it installed to the default action before its last steps (Blender's
    teardown takes a good part of a second), where a signal would end the process by
    the signal instead of with the command's code; an ignored one it leaves ignored."""
    for s in stop_signals():
        signal.signal(s, signal.SIG_IGN)


def raise_noted():
    """Where a command starts: forget an earlier command's stop (``stop_raised``) and
    raise a stop signal noted since the start (outside any ``held()`` block)."""
    _state["raised"] = None
    pending = _state["pending"]
    if pending is not None and not _state["held"]:
        _state["pending"] = None
        _raise(pending)


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
            _raise(pending)


def deliver(signum):
    """What the command line's handler does with stop signal ``signum``: raise it now,
    or note it for the end of a ``held()`` block."""
    if _state["held"]:
        if _state["pending"] is None:
            _state["pending"] = int(signum)
        return
    _raise(signum)


def _raise(signum):
    _state["raised"] = int(signum)
    raise Interrupted(signum)


def stop_raised():
    """The stop signal raised as ``Interrupted`` in this process, or None: a library
    may turn the exception into one of its own (numpy's import turns it into an
    ImportError), and the command line still reports a stop."""
    return _state["raised"]
