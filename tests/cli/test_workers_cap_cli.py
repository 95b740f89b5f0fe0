"""--workers N beyond this machine's cores is capped with a notice, not 64 processes."""

import json
import os

from .conftest import rls


def test_workers_beyond_the_cores_are_capped(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    proc = rls("scan", blend, "--frames", "1-4", "--out", tmp_path, "--workers", "64")
    assert proc.returncode == 0, proc.stderr[-3000:]
    cores = len(os.sched_getaffinity(0))
    told = [ln for ln in proc.stderr.splitlines() if ln.startswith("rls: notice: --workers 64")]
    assert len(told) == 1 and f"capped at {cores}" in told[0], proc.stderr
    assert "Traceback" not in proc.stderr
    if cores > 1:
        assert f"on {cores} Dask worker(s)" in proc.stderr
    assert json.loads(proc.stdout)["scanned"] == 4
