"""Frames outside the traffic's keys are refused, naming them and the span."""

import pytest

from rls_addon.core.errors import SceneError
from rls_addon.core.scene.traffic_keys import check_keyed, frame_ranges, source_span


def test_frame_ranges():
    assert frame_ranges([9, 1, 2, 3, 7, 10, 11, 12, 2]) == "1-3, 7, 9-12"
    assert frame_ranges([5]) == "5"


def test_frames_within_the_keys_pass_outside_are_refused():
    check_keyed(range(3, 22), (3, 21))
    check_keyed([500], None)  # no keyed traffic: nothing to check
    with pytest.raises(SceneError, match=r"^frames 22-200 after its last key \(frame 21\): "
                                         r"the traffic is keyed over frames 3-21"):
        check_keyed(range(3, 201), (3, 21))
    with pytest.raises(SceneError, match=r"traffic frames 1-2 before its first key \(frame 3\)"):
        check_keyed([1, 2, 3], (3, 21), "traffic frames")


def test_a_source_that_does_not_say_has_no_span():
    class Quiet:
        pass

    class Keyed:
        def traffic_span(self):
            return (1, 60)

    assert source_span(Quiet()) is None and source_span(Keyed()) == (1, 60)
