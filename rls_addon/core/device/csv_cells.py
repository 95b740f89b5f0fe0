"""Cells of the small CSV files RLS reads (angle tables, firing times, custom scan
patterns)."""

import math


def finite_number(text, where, line, column, error):
    """The cell ``text`` as a finite float, else ``error`` (an ``RLSError`` class) with
    a message naming the file, line and column."""
    try:
        v = float(text)
    except ValueError:
        raise error(f"{where} line {line}: column '{column}' must be a number, "
                    f"got '{text.strip()}'") from None
    if not math.isfinite(v):
        raise error(f"{where} line {line}: column '{column}' must be finite, got {v}")
    return v


def commented_rows(text):
    """``(rows, source, note)`` of a small CSV's ``text``: ``rows`` the
    ``(line number, line, cells)`` of its lines but blank and ``#`` comment lines (cells
    stripped), ``source`` and ``note`` what its ``# source:`` and ``# note:`` lines say."""
    source = note = ""
    rows = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if body.startswith("source:"):
                source = body[len("source:"):].strip()
            elif body.startswith("note:"):
                note = body[len("note:"):].strip()
            continue
        rows.append((lineno, line, [c.strip() for c in line.split(",")]))
    return rows, source, note
