"""The number lists users type, read the same way by the command line and the panels:
values (``10``, ``0,10,20``, ``0:30:10``) and frames (``5``, ``1-10``, ``1-10:2``).
``what`` names the setting in the error (``--pitch`` on the command line, the field's
label in a panel)."""

import math

from .errors import RegionError, SceneError


def parse_values(text, what="values"):
    """'10' -> [10.0]; '0,10,20' -> list; '0:30:10' -> 0,10,20,30 (inclusive range)."""
    if isinstance(text, (int, float)):
        return [float(text)]
    text = str(text).strip()
    bad = RegionError(f"{what}: expected V, V1,V2,... or START:STOP:STEP, got {text!r}")
    try:
        if ":" in text:
            parts = [float(t) for t in text.split(":")]
            if len(parts) != 3 or parts[2] <= 0:
                raise bad
            a, b, step = parts
            count = int(math.floor((b - a) / step + 1e-9)) + 1
            if count < 1:
                raise bad
            return [round(a + i * step, 9) for i in range(count)]
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise bad from None
    if not vals:
        raise RegionError(f"{what}: no values in {text!r}")
    return vals


def parse_frames(text, current, what="--frames"):
    """'5' -> [5]; '1-10' -> 1..10; '1-10:2' -> 1,3,..,9; None -> [current]."""
    if text is None:
        return [current]
    try:
        rng, _, step = text.partition(":")
        a, sep, b = rng.partition("-")
        start, end = int(a), int(b) if sep else int(a)
        step = int(step) if step else 1
    except ValueError:
        raise SceneError(f"{what}: expected N, A-B or A-B:STEP, got '{text}'") from None
    if end < start or step < 1:
        raise SceneError(f"{what}: empty range '{text}'")
    return list(range(start, end + 1, step))
