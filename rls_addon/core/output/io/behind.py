"""A writer's files written behind the scan: each write on one background thread while
the next scans run (encoding, writing and syncing a driving lidar's files cost about a
third of its scan), the writes one after another in the order given.

Up to ``WRITES_BEHIND`` writes wait their turn, so one slow fsync (a journal commit:
10 ms among 3 ms frames) does not hold the scan up; a failed write raises at a later
write or at ``flush`` (the end of a run, a cancel), once nothing runs behind it. The
writer must not change what it handed over (a scan's points and info) meanwhile.

A scan's info may also hold values left to work out when its files are written
(``Later``: a driving lidar's ground-truth boxes, 12-16 ms of a traffic frame, much of
it compiled or in large numpy steps that let go of Python's lock): they are worked
out on the same thread, just before the write that needs them, while the next scans
run; their errors surface as the write's. Where writing is not behind, at once.
"""

import threading
from collections import deque

from ...stop_signals import held

WRITES_BEHIND = 4

_THREAD = []


class WritesBehind:
    """The background writes of one writer (``enabled``; else each write runs at once,
    in the caller)."""

    def __init__(self, enabled=True):
        self.enabled = bool(enabled)
        self.pending = deque()  # writes under way (Futures), oldest first

    def __getstate__(self):  # sent to workers without a write under way
        return {"enabled": self.enabled, "pending": deque()}

    def run(self, fn, *args):
        """``fn(*args)``: behind the scan when enabled (returns None), else now (returns
        its result). The ``Later`` values of any dict among ``args`` (a scan's info) are
        worked out first, on the same thread, and put in their place."""
        if not self.enabled:
            return _worked_out(fn, *args)
        self.make_room()
        with held():  # the hand-over whole: the first starts the thread (_background_thread)
            self.pending.append(_background_thread().submit(_worked_out, fn, *args))
        return None

    def flush(self):
        """Wait for every write under way; raises what the first that failed raised
        (after all of them ended)."""
        failed = None
        while self.pending:
            try:
                _wait(self.pending[0])
            except BaseException as exc:  # noqa: BLE001 - the rest still end first
                failed = failed or exc
            self.pending.popleft()
        if failed is not None:
            raise failed

    def make_room(self, bound=None):
        """Take the writes that ended (raising what one raised), and wait for the oldest
        while ``WRITES_BEHIND`` are under way."""
        bound = WRITES_BEHIND if bound is None else bound
        while self.pending and (self.pending[0].done() or len(self.pending) >= bound):
            try:
                _wait(self.pending[0])
            except BaseException:
                self.flush()  # nothing left running behind the error
                raise
            self.pending.popleft()


class Later:
    """A value of a scan's info left to be worked out when its files are written
    (``work()``, once; see the module docstring). Calling it gives the value."""

    def __init__(self, work):
        self._work = work
        self._lock = threading.Lock()
        self._value = None

    def __call__(self):
        with self._lock:
            if self._work is not None:
                self._value = self._work()
                self._work = None  # what it worked from (a frame's rays) can go
            return self._value


def worked_out(info):
    """``info`` (a dict) with its ``Later`` values worked out and put in their place."""
    for key, value in list(info.items()):
        if isinstance(value, Later):
            info[key] = value()
    return info


def _worked_out(fn, *args):
    for a in args:
        if isinstance(a, dict):
            worked_out(a)
    return fn(*args)


def _wait(write):
    """The result of ``write`` (a Future). A stop signal raised while waiting for it
    (the command line's handler raises in the main thread) is raised only once the
    write has ended: a write is never left running when the run winds down."""
    try:
        return write.result()
    except BaseException:
        if not write.done():
            from concurrent.futures import wait

            wait([write])
        raise


def _background_thread():
    """The one thread background writes run on (started on first use).

    Started with stop signals held (``WritesBehind.run``): Python 3.11's
    ``ThreadPoolExecutor.submit`` starts its thread and only then notes it among the
    threads to stop at exit; a stop signal raised in between (a SIGTERM while the new
    thread is scheduled, a window of milliseconds on a loaded machine) left a thread
    nobody stops, and the process, its files complete and its message said, waited for
    it at exit for ever (tests/core/test_writes_behind_stop.py)."""
    if not _THREAD:
        from concurrent.futures import ThreadPoolExecutor

        _THREAD.append(ThreadPoolExecutor(1, thread_name_prefix="rls-writer"))
    return _THREAD[0]
