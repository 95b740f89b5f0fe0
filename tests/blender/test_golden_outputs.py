"""Byte-for-byte regression: clouds and study tables equal the golden checksums
recorded before the scan run moved into the core (``tests/golden/record.py``); a
change is reported case by case with what changed in it (points, fields)."""

import json

from tests.golden import record


def test_outputs_match_the_golden_checksums(scene):
    want = json.loads(record.CHECKSUMS.read_text())
    summaries = {}
    got = record.compute(summaries)
    lines = record.changes(want, got, json.loads(record.SUMMARIES.read_text()), summaries)
    assert not lines, "outputs changed against tests/golden (review, then record.py --write):\n" \
        + "\n".join(lines)
