"""Cells of the small CSV files RLS reads (angle tables, custom scan patterns)."""

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
