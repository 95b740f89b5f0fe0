"""core.stop_signals: a stop signal waits for the end of a held step, in the main thread;
a background write holds nothing and never takes a signal."""

import threading

import pytest

from rls_addon.core import stop_signals
from rls_addon.core.errors import Interrupted


def test_a_signal_in_a_held_step_is_raised_when_it_ends():
    done = []
    with pytest.raises(Interrupted) as got:
        with stop_signals.held():
            with stop_signals.held():  # nested: the outermost decides
                stop_signals.deliver(15)
                done.append("inner")
            done.append("outer")  # the step runs to its end
    assert done == ["inner", "outer"] and got.value.exit_code == 143
    with pytest.raises(Interrupted):  # outside a held step: at once
        stop_signals.deliver(1)
    with stop_signals.held():  # nothing left pending from before
        pass


def test_a_background_thread_holds_nothing():
    """The cloud writer writes behind the scan in a thread: its atomic writes hold, but a
    signal arriving then (in the main thread) must stop the main thread, not be noted
    for the writer's thread to raise."""
    inside, release, out = threading.Event(), threading.Event(), []

    def writer():
        with stop_signals.held():
            inside.set()
            release.wait(5)
        out.append("written")

    t = threading.Thread(target=writer)
    t.start()
    inside.wait(5)
    with pytest.raises(Interrupted):
        stop_signals.deliver(15)  # the main thread holds nothing: raised here
    release.set()
    t.join(5)
    assert out == ["written"]


@pytest.fixture
def handlers():
    """The stop signals' handlers, put back after the test."""
    import signal

    saved = {s: signal.getsignal(s) for s in stop_signals.stop_signals()}
    stop_signals._state.update(pending=None, raised=None)
    yield
    for s, h in saved.items():
        signal.signal(s, h)
    stop_signals._state.update(pending=None, raised=None)


def test_signals_from_the_start_are_noted_then_raised_where_the_command_starts(handlers):
    """``python -m rls_addon``'s first line notes stop signals (Ctrl-C included, which
    Python would raise in whatever import is under way); the command line raises the
    first one where the command starts, and reports it as a stop however a library
    turned it (``stop_raised``)."""
    import os
    import signal

    stop_signals.note_from_start()
    os.kill(os.getpid(), signal.SIGINT)  # handled now: noted, not raised
    os.kill(os.getpid(), signal.SIGTERM)  # the first one counts
    assert stop_signals.stop_raised() is None
    with pytest.raises(Interrupted) as got:
        stop_signals.raise_noted()
    assert got.value.exit_code == 130 and stop_signals.stop_raised() == signal.SIGINT
    stop_signals.raise_noted()  # nothing left; a new command forgets the last one's stop
    assert stop_signals.stop_raised() is None
    stop_signals.ignore_after_end()  # the command has ended: Python's shutdown takes none
    os.kill(os.getpid(), signal.SIGHUP)
    assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN


def test_a_signal_while_the_command_line_puts_its_handlers_back_is_ignored(handlers,
                                                                          monkeypatch):
    """A stop that lands after a command has ended, while ``cli.main`` restores the
    handlers it replaced one signal at a time (the others still its own), finds the
    command ended: main returns the command's code instead of raising from its
    ``finally`` (a traceback after the last frame, seen under load in the start-up
    signal test)."""
    import os
    import signal

    from rls_addon import cli

    restoring = []
    real = signal.signal

    def restore_then_signal(signum, handler):
        previous = real(signum, handler)
        restores = getattr(previous, "__name__", "") == "stop" and handler is not previous
        if restores and not restoring:  # the first handler put back
            restoring.append(signum)
            other = next(s for s in stop_signals.stop_signals() if s != signum)
            os.kill(os.getpid(), other)  # its handler is still the command line's
        return previous

    monkeypatch.setattr(cli.signal, "signal", restore_then_signal)
    assert cli.main(["--version"]) == 0
    assert restoring


def _command_line_running(monkeypatch, command):
    """``cli.main`` running ``command`` as its one command."""
    import argparse

    from rls_addon import cli

    parser = argparse.ArgumentParser()
    parser.set_defaults(func=command)
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    return cli.main([])


def _dropping(exc_or_signal):
    """An object whose weakref callback, run when it goes, raises ``exc_or_signal``
    or takes that signal: Python drops what the callback raises ("Exception ignored
    in ...")."""
    import signal
    import weakref

    class Thing:
        pass

    def callback(_):
        if isinstance(exc_or_signal, Exception):
            raise exc_or_signal
        signal.raise_signal(exc_or_signal)

    thing = Thing()
    return thing, weakref.ref(thing, callback)


def test_a_stop_python_drops_is_raised_again_at_the_next_call(handlers, monkeypatch, capsys):
    """A stop signal that lands in a weakref callback (the import system's module-lock
    clean-up, seen under load in the start-up signal test) raised ``Interrupted``
    there; Python dropped it with an "Exception ignored" traceback and the run went on
    to its end with exit 0. It is raised again as the next call of an RLS function that
    is not a finalizer begins, and nothing is printed for the drop. A finalizer of
    RLS's called meanwhile runs whole: a cast dropped then still joins its threads
    (raised at its ``__del__``, the stop left them writing into freed arrays: a
    SIGSEGV in CI)."""
    import signal
    import sys

    from rls_addon.core.casting import embree_loop

    steps, dropped, joined = [], [], []

    def step():  # not RLS's: a library's code, say
        steps.append("a call outside RLS")

    def command(args):
        batch = embree_loop._Batch(joined.append, 5, ("the rays",), ("the hits",))
        thing, ref = _dropping(signal.SIGHUP)
        del thing  # the callback takes the signal; its Interrupted is dropped
        steps.append("went on")  # no Python call yet
        step()
        del batch  # RLS's finalizer: not where the stop is raised
        steps.append("finalized")
        stop_signals.stop_signals()  # the run's next step: RLS's
        steps.append("ran to the end")

    monkeypatch.setattr(sys, "unraisablehook", dropped.append)
    assert _command_line_running(monkeypatch, command) == 129
    assert steps == ["went on", "a call outside RLS", "finalized"] and dropped == []
    assert joined == [5]
    assert capsys.readouterr().err.startswith("rls: interrupted")
    assert sys.unraisablehook == dropped.append and sys.getprofile() is None


def test_other_dropped_exceptions_are_reported_as_before(handlers, monkeypatch):
    import sys

    dropped = []

    def command(args):
        thing, ref = _dropping(ValueError("not a stop"))
        del thing

    monkeypatch.setattr(sys, "unraisablehook", dropped.append)
    assert _command_line_running(monkeypatch, command) == 0
    assert [str(d.exc_value) for d in dropped] == ["not a stop"]


def test_a_command_ends_with_no_cast_left_running(handlers, monkeypatch):
    """A stopped run's cast under way goes, and waits, with the run's frames; held in a
    reference cycle (a traceback's frames hold their own exception) it could outlive the
    command, its threads still casting while the process tears Embree down. The command
    line waits for every cast left when a command ends."""
    from rls_addon.core.casting import embree_loop

    finished, kept = [], []

    def command(args):
        kept.append(embree_loop._Batch(finished.append, 9, ("the rays",), ("the hits",)))
        raise Interrupted(15)  # stopped with the cast under way

    assert _command_line_running(monkeypatch, command) == 143
    assert finished == [9]  # joined before main returned, though still referenced
    kept[0]()  # collected later: nothing left to wait for
    assert finished == [9]
