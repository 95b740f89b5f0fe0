"""ASCII rows for point records: shortest text that reads back to the same value."""

import numpy as np

from ...errors import InputError


def _spec(dt):
    if dt.kind == "f":
        return "%.9g" if dt.itemsize == 4 else "%.17g"
    return "%d"


def ascii_rows(records):
    """Encoded text, one space-separated row per record, each ending in a newline."""
    names = records.dtype.names
    if len(records) == 0:
        return b""
    fmt = " ".join(_spec(records.dtype[f]) for f in names)
    cols = [records[f].tolist() for f in names]
    text = "\n".join(map(fmt.__mod__, zip(*cols)))
    return (text + "\n").encode("ascii")


def parse_rows(text, dtype, count):
    """Parse ``count`` whitespace-separated rows of ``dtype`` records."""
    flat = []
    for f in dtype.names:
        sub = dtype[f]
        flat.append(int(np.prod(sub.shape)) if sub.shape else 1)
    width = sum(flat)
    tokens = text.split()
    if len(tokens) < width * count:
        raise InputError(f"expected {count} rows of {width} values, found {len(tokens)} values")
    out = np.empty(count, dtype=dtype)
    if count == 0:
        return out
    # float64 holds every value we write exactly (%.17g doubles, 32-bit ints)
    table = np.array(tokens[: width * count], dtype=np.float64).reshape(count, width)
    col = 0
    for f, w in zip(dtype.names, flat):
        out[f] = table[:, col:col + w].reshape(out[f].shape)
        col += w
    return out
