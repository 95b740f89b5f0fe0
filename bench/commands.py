"""``python -m rls_addon ...`` run as a user runs it, in a subprocess, timed."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def rls(*args, timeout=7200):
    """(the command's JSON summary, wall seconds); a failed command raises with the end
    of its stderr."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "rls_addon", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"rls {args[0]} failed: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout[proc.stdout.index("{"):]), time.perf_counter() - t
