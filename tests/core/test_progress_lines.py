"""core.progress: the estimate of a progress line."""

from rls_addon.core.progress import left_text


def test_no_estimate_before_anything_is_done():
    assert left_text(0, 10, 3.0) == ""  # no rate yet: never "about nan s left"
    assert left_text(0.0, 1.0, 0.5) == ""
    assert left_text(5, 10, 3.0) == ", about 3 s left"
    assert left_text(10, 10, 7.0) == ", about 0 s left"
