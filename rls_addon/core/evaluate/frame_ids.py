"""Frame numbers from the names other tools give frames.

RLS's dataset layouts name a frame's files by its scene frame number, six digits
(``datasets.common.frame_id``: frame 12 -> ``000012``); OpenPCDet hands that name on
as ``frame_id`` (its ``ImageSets`` lines), OPV2V/OpenCOOD as the timestamp key."""

import re

from ..errors import InputError

_DIGITS = re.compile(r"^\s*\d+\s*$")


def frame_number(text, where):
    """The frame number of an id such as '000012' (12); ``InputError`` naming ``where``
    when it is not a whole number >= 0."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    s = str(text)
    if not _DIGITS.match(s):
        raise InputError(f"{where}: frame id {s!r} is not a frame number (RLS names frames "
                         "by their number, six digits: 000012)")
    return int(s)


__all__ = ["frame_number"]
