"""A frame's freed arrays are kept for the next frame (core/scan/freed_pages.py): with the
thresholds set, a round of frame-like allocations faults almost no page in; without,
every page again. Each case runs in a fresh interpreter, since glibc's thresholds are
per process and move with its history."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rls_addon.core.scan import freed_pages

ROOT = Path(__file__).resolve().parents[2]

# Rounds like a frame's: a dozen arrays of 2-4 MB, each written in full, all freed at
# the end (more freed at once than twice the largest: glibc's own rule gives it back).
ROUNDS = r"""
import json, resource, sys
import numpy as np
from rls_addon.core.scan import freed_pages
state = freed_pages.keep_freed_pages()
def round_():
    arrays = [np.ones((2 + k % 3) * 2 ** 17) for k in range(12)]  # 2-4 MB each
    return sum(a.nbytes for a in arrays)
round_()
round_()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
touched = sum(round_() for _ in range(5)) // 4096
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
print(json.dumps({"state": state, "faults": faults, "pages": touched}))
"""

glibc = pytest.mark.skipif(freed_pages._glibc() is None, reason="glibc's allocator only")


def _run(**env):
    base = {k: v for k, v in os.environ.items()
            if k not in freed_pages.USER_SWITCHES and k != "RLS_KEEP_FREED_PAGES"}
    proc = subprocess.run([sys.executable, "-c", ROUNDS], env={**base, **env}, cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@glibc
def test_kept_pages_are_not_faulted_in_again():
    got = _run()
    assert got["state"] == "set"
    assert got["faults"] < 0.02 * got["pages"], got


@glibc
def test_without_it_every_round_faults_its_pages_in():
    # the control: the rounds above do churn pages when the thresholds are left alone,
    # so the test before can fail
    got = _run(RLS_KEEP_FREED_PAGES="0")
    assert got["state"].startswith("off")
    assert got["faults"] > 0.5 * got["pages"], got


@glibc
def test_the_users_own_setting_is_left_alone():
    got = _run(MALLOC_TRIM_THRESHOLD_="65536")
    assert got["state"] == "left as the environment sets it"
    assert got["faults"] > 0.5 * got["pages"], got


def test_answers_once_per_process(monkeypatch):
    monkeypatch.setattr(freed_pages, "_state", None)
    assert freed_pages.keep_freed_pages({"MALLOC_TOP_PAD_": "0"}) == \
        "left as the environment sets it"
    # a later call, whatever its environment, gives the first answer
    assert freed_pages.keep_freed_pages({}) == "left as the environment sets it"


def test_elsewhere_nothing_is_changed(monkeypatch):
    monkeypatch.setattr(freed_pages, "_state", None)
    monkeypatch.setattr(freed_pages, "_glibc", lambda: None)
    assert freed_pages.keep_freed_pages({}) == "not glibc's allocator"
