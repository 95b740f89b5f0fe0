"""A cast running on the compiled loop's threads (``embree_loop._Batch``), dropped
uncalled while a stop signal is raised as its wait begins (a handler may raise at any
call), still joins its workers before the arrays they read and write go with it."""

import sys

from rls_addon.core.casting import embree_loop
from rls_addon.core.errors import Interrupted


def test_a_batch_dropped_with_a_stop_at_its_wait_still_joins_its_workers(monkeypatch):
    finished, dropped, waits = [], [], []
    wait = embree_loop._Batch._wait

    def stopped_at_first(self):
        waits.append(self)
        if len(waits) == 1:
            raise Interrupted(2)  # what the command line's handler raises for Ctrl-C
        wait(self)

    monkeypatch.setattr(embree_loop._Batch, "_wait", stopped_at_first)
    monkeypatch.setattr(sys, "unraisablehook", dropped.append)
    batch = embree_loop._Batch(finished.append, 7, ("the rays",), ("the hits",))
    del batch  # dropped uncalled: its __del__ waits
    assert finished == [7]  # the workers joined once
    # the stop goes on: Python drops what __del__ raises (the command line raises a
    # dropped stop again, tests/core/test_stop_signals.py)
    assert [type(d.exc_value) for d in dropped] == [Interrupted]
