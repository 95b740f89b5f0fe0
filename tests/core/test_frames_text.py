"""Frames as a user writes them (--frames and its kin): each mistake is one SceneError,
never a traceback (a range of 10^11 frames was a MemoryError)."""

import pytest

from rls_addon.core.errors import SceneError
from rls_addon.core.scan.frames import MAX_FRAME, parse_frames


def test_frames_as_written():
    assert parse_frames(None, 7) == [7]
    assert parse_frames("5", 1) == [5]
    assert parse_frames("1-4", 1) == [1, 2, 3, 4]
    assert parse_frames("1-9:4", 1) == [1, 5, 9]
    assert parse_frames(f"{MAX_FRAME}", 1) == [MAX_FRAME]


@pytest.mark.parametrize("text,words", [
    ("5-1", "empty range '5-1'"),
    ("1-10:0", "empty range"),
    ("-3", "expected N, A-B or A-B:STEP"),
    ("1.5", "expected N, A-B or A-B:STEP"),
    ("1-99999999999", f"frame 99999999999 is past Blender's last frame ({MAX_FRAME})"),
    (f"{MAX_FRAME + 1}", "past Blender's last frame"),
    ("1-" + "9" * 30 + ":1000", "past Blender's last frame"),
])
def test_frames_that_are_mistakes_are_one_error(text, words):
    with pytest.raises(SceneError) as exc:
        parse_frames(text, 1)
    assert words in str(exc.value)
