"""The ``rls`` command line: one parser for ``python -m rls_addon`` and
``blender -b scene.blend -c rls``. Errors become one line on stderr and exit code 1."""

import argparse
import re
import signal
import sys
import threading

from .commands import load_commands
from .commands.stderr import say
from .core.errors import RLSError, interrupt_exit_code
from .core.stop_signals import (deliver, held, raise_dropped_stops, raise_noted, stop_raised,
                                stop_signals)
from .version import VERSION


def build_parser():
    parser = argparse.ArgumentParser(
        prog="rls", description="Realistic LiDAR simulation for Blender scenes.")
    parser.add_argument("--version", action="version", version=f"rls {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for mod in load_commands():
        mod.add_parser(sub)
    return parser


# A list or range that starts with a negative number: "-20:20:20", "-10,0,10"; or a
# negative number with an exponent, "-1e12", "-2.5E-3" (argparse knows "-5" and "-1.5"
# for numbers, not these)
NEGATIVE_LIST = re.compile(r"^-\d[\d.]*(?:[:,]-?\d[\d.]*)+$"
                           r"|^-(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


def joined_negative_values(argv):
    """``--yaw -20:20:20`` as ``--yaw=-20:20:20`` (and ``--start-time -1e12`` as
    ``--start-time=-1e12``): argparse takes a value that starts with "-" and is not a
    plain number for an option and stops with "expected one argument"."""
    out = []
    for arg in argv:
        if out and NEGATIVE_LIST.match(arg) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out


def main(argv=None, prepare_blender=None):
    """Run one command; return the process exit code. ``prepare_blender`` registers
    the extension in this Blender (the entry points pass ``ensure_registered``); the
    commands that open a scene call it (``args.prepare_blender``)."""
    _command["ended"] = False
    previous = _stop_on_signals()
    unraisable = sys.unraisablehook
    sys.unraisablehook = raise_dropped_stops(unraisable)
    try:
        raise_noted()  # a stop signal that came while Python loaded RLS stops it here
        with held():  # the commands' modules (numpy, ...) are imported whole
            parser = build_parser()
        try:
            args = parser.parse_args(joined_negative_values(sys.argv[1:] if argv is None
                                                            else argv))
        except SystemExit as exc:  # --help, --version, usage errors
            return int(exc.code or 0)
        args.prepare_blender = _held(prepare_blender or _nothing)
        return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:
        return _interrupted(interrupt_exit_code(exc))
    except Exception as exc:
        if stop_raised() is not None:  # a library turned the stop into its own error (an
            return _interrupted(128 + stop_raised())  # import into an ImportError): a stop
        if not isinstance(exc, RLSError):
            raise
        say(f"rls: error: {exc}")
        return 1
    finally:
        # a signal from here on finds the command ended (its code decided, its files
        # complete): ignored, never raised inside this loop, which restores the handlers
        # one signal at a time
        _command["ended"] = True
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        sys.unraisablehook = unraisable
        _casts_joined()


def _casts_joined():
    """No cast left running on the compiled loop's threads once a command has ended
    (``embree_loop.wait_for_casts``; nothing to do where no cast was made)."""
    loop = sys.modules.get(f"{__package__}.core.casting.embree_loop")
    if loop is not None:
        loop.wait_for_casts()


STOP_SIGNALS = stop_signals()
_command = {"ended": False}


def _interrupted(code):
    say("rls: interrupted: files already written are complete, none is left half-written")
    return code


def _held(prepare_blender):
    """``prepare_blender`` (registering the extension: Blender runs its own scripts)
    with stop signals held until it is done."""
    def prepare():
        with held():
            prepare_blender()
    return prepare


def _stop_on_signals():
    """SIGINT (Ctrl-C), SIGTERM and SIGHUP raise ``Interrupted`` (a KeyboardInterrupt),
    or wait for the end of a step that must not be cut (``core.stop_signals.held``: loading
    Blender), so every command stops the same way: the write under way ends or its
    temporary is removed, and the exit code is 128 + the signal (130, 143, 129). The
    first signal counts; a repeat while the run winds down is ignored. Returns the
    handlers replaced (restored when the command ends)."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def stop(signum, frame):
        if _command["ended"]:
            return
        for s in STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        deliver(signum)  # now, or where a step that must not be cut ends

    return {s: signal.signal(s, stop) for s in STOP_SIGNALS}


def _nothing():
    pass
