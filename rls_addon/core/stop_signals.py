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

Python drops an exception raised where it cannot pass one on (a weakref callback such as
its import system's module-lock clean-up, a ``__del__``): it prints "Exception ignored
in ..." and goes on. A stop raised there would be lost and the run would go on to its
end; ``raise_dropped_stops`` raises it again as the main thread's next call of an RLS
function that is not a finalizer begins.
"""

import contextlib
import os
import signal
import sys
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


_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _may_take_stop(code):
    """Whether a stop may be raised as a call of ``code`` begins: a function of RLS's
    own (the run calls them all the time), not a finalizer. A finalizer (``__del__``,
    a weakref callback) is called where Python drops what it raises, and what it
    guards would go undone: a cast's ``__del__`` joins the threads that write into the
    arrays going with it (a stopped dataset crashed with SIGSEGV when the stop was
    raised again there)."""
    return (code.co_name != "__del__"
            and os.path.abspath(code.co_filename).startswith(_PACKAGE + os.sep))


def raise_dropped_stops(previous):
    """A ``sys.unraisablehook`` for while the command line takes the stop signals:
    ``Interrupted`` dropped in the main thread is raised again, silently, as the next
    call of an RLS function that is not a finalizer begins (``_may_take_stop``; where
    a step is held, at the step's end); anything else goes to ``previous``. A profiler
    set with ``sys.setprofile`` misses the events between the drop and that call."""
    def hook(unraisable):
        signum = _state["raised"]
        if (not isinstance(unraisable.exc_value, Interrupted) or signum is None
                or threading.current_thread() is not threading.main_thread()):
            previous(unraisable)
            return
        before = sys.getprofile()

        def at_next_call(frame, event, arg):
            if event == "call" and _may_take_stop(frame.f_code):
                sys.setprofile(before)
                deliver(signum)

        sys.setprofile(at_next_call)
    return hook


def stop_raised():
    """The stop signal raised as ``Interrupted`` in this process, or None: a library
    may turn the exception into one of its own (numpy's import turns it into an
    ImportError), and the command line still reports a stop."""
    return _state["raised"]
