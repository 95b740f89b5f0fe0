"""Byte-for-byte regression: clouds and study tables equal the golden checksums
recorded before the scan run moved into the core (``tests/golden/record.py``)."""

import json

from tests.golden import record


def test_outputs_match_the_golden_checksums(scene):
    want = json.loads(record.CHECKSUMS.read_text())
    got = record.compute()
    assert sorted(got) == sorted(want)
    changed = {k: (want[k], got[k]) for k in want if got[k] != want[k]}
    assert not changed, f"outputs changed (golden, now): {changed}"
