"""A stop signal that arrives while the writer's background thread starts (the first
write handed over) still lets the process end: Python 3.11's ThreadPoolExecutor starts
its thread and only then notes it among the threads it stops at exit, so a stop raised
in between left a thread that nobody stopped, and the process, its message said, waited
for it at exit for ever (a CI run under load: ``rls scan`` stopped by SIGTERM
during its first frame never exited). The hand-over holds stop signals
(``behind.WritesBehind.run``)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# In a process of its own (the writer's thread is started once per process): the stop
# signal delivered as the command line's handler delivers it, at the moment the new
# thread has started (the handler runs when the main thread resumes).
# (the next thread started: the stop delivered as soon as it runs)
STOP_AT_THREAD_START = r"""
import sys, threading
from rls_addon.core import stop_signals
start = threading.Thread.start
def started_then_stopped(self):
    start(self)
    threading.Thread.start = start
    stop_signals.deliver(15)
threading.Thread.start = started_then_stopped
"""

SCRIPT = STOP_AT_THREAD_START + r"""
from rls_addon.core.output.io import behind

wrote = []
try:
    behind.WritesBehind(True).run(wrote.append, "frame 1")
except KeyboardInterrupt as exc:
    print("stopped", exc.exit_code, flush=True)
sys.exit(143)
"""


def _ends_stopped(script):
    """Run ``script`` in a process of its own; it must end, stopped (exit 143, having
    said so)."""
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        # a bound for a process that never ends, far above its fraction of a second
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, err
    assert out.split() == ["stopped", "143"], (out, err)


def test_a_stop_while_the_writer_thread_starts_lets_the_process_end():
    _ends_stopped(SCRIPT)


# The same for the Embree caster's packet-mode pool (without the compiled loop): its
# tasks are handed over with stop signals held too.
CAST_SCRIPT = r"""
import numpy as np
from rls_addon.core.casting.embree import EmbreeCaster

v = np.array([[-50.0, -50.0, -1.0], [50.0, -50.0, -1.0], [0.0, 50.0, -1.0]])
caster = EmbreeCaster(v, np.array([[0, 1, 2]]), threads=2, mode="packets", native=False)
d = np.random.default_rng(0).normal(size=(20000, 3))
d /= np.linalg.norm(d, axis=1, keepdims=True)
""" + STOP_AT_THREAD_START + r"""
try:
    caster.cast(np.zeros((1, 3)), d, 100.0)
except KeyboardInterrupt as exc:
    print("stopped", exc.exit_code, flush=True)
sys.exit(143)
"""


def test_a_stop_while_the_caster_pool_starts_lets_the_process_end():
    _ends_stopped(CAST_SCRIPT)
