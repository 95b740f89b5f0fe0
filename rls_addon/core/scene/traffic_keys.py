"""Frames outside the traffic's keys: refused, never scanned frozen.

Road users (objects labelled vehicle, pedestrian or cyclist) animated by keyframes hold
their last keyed pose after their last key and their first before their first: a scan
there sees the traffic standing frozen, which no road does. A scene source may say over
which frames its road users are keyed (``traffic_span()``: (first, last) frame of any
road user's keys, None without keyed road users); a run, dataset or study asked for
frames outside that span is refused before anything is scanned, naming the frames and
the span.
"""

from ..errors import SceneError


def frame_ranges(frames):
    """'1-3, 7, 9-12' of sorted distinct ``frames``."""
    fs = sorted(set(int(f) for f in frames))
    parts, start = [], None
    for i, f in enumerate(fs):
        if start is None:
            start = f
        if i + 1 == len(fs) or fs[i + 1] != f + 1:
            parts.append(f"{start}" if start == f else f"{start}-{f}")
            start = None
    return ", ".join(parts)


def source_span(source):
    """(first, last) frame of ``source``'s keyed road users, or None (a source that
    does not say: a test's fake, say)."""
    span = getattr(source, "traffic_span", None)
    return span() if callable(span) else None


def check_keyed(frames, span, what="frames"):
    """``SceneError`` when any of ``frames`` lies outside ``span`` (first, last) of the
    traffic's keys (None: no keyed traffic, nothing to check)."""
    if span is None or not len(frames):
        return
    first, last = int(span[0]), int(span[1])
    after = [f for f in frames if f > last]
    before = [f for f in frames if f < first]
    if not after and not before:
        return
    where = []
    if after:
        where.append(f"{frame_ranges(after)} after its last key (frame {last})")
    if before:
        where.append(f"{frame_ranges(before)} before its first key (frame {first})")
    raise SceneError(
        f"{what} {' and '.join(where)}: the traffic is keyed over frames {first}-{last} "
        f"and would stand frozen outside them; choose frames within {first}-{last}, or "
        f"import traffic over a longer stretch (rls traffic import --begin/--end)")
