"""Labels from names (core/labels.py): Blender's duplicate suffix is not part of a name's
meaning, so a "Road.001" collection (what Blender calls a second "Road" in one file, as
*Import SUMO Network as Scene* makes one beside a scene that has its own) is road."""

import pytest

from rls_addon.core.errors import RLSError
from rls_addon.core.labels import base_name, label_id, match_label


def test_duplicate_suffix_left_out():
    assert match_label("Road") == match_label("Road.001") == match_label("road.1234") == 1
    assert match_label("Cars.012") == match_label("Vehicles") == 11
    assert base_name("Road.001") == "Road" and base_name("Road.1") == "Road.1"
    assert match_label("Road.1") is None  # not Blender's suffix: no class
    assert label_id("Sidewalk.002") == 2
    with pytest.raises(RLSError):
        label_id("Roads and more.001")
