"""Where ``rls lidar add`` puts a LiDAR (core/scene/mounting.py): the aim against
analytic directions, and every bad input refused with one ``SceneError``."""

import math
import re

import numpy as np
import pytest

from rls_addon.core.errors import SceneError
from rls_addon.core.scene.mounting import LidarMounting, check_name, parse_position
from rls_addon.core.study.candidates import orientation_matrix, pose_matrix


def forward(euler):
    """World direction of the sensor's +X for XYZ Euler angles (Blender's order)."""
    roll, pitch, yaw = euler
    return orientation_matrix(yaw, pitch, roll) @ np.array([1.0, 0.0, 0.0])


def test_aim_by_yaw_pitch_and_facing_the_region():
    m = LidarMounting(preset="hesai_pandar64", at=(0, 0, 5), pitch_deg=30, yaw_deg=90)
    c = math.cos(math.radians(30))
    assert forward(m.euler(m.at)) == pytest.approx([0.0, c, -0.5], abs=1e-12)
    level = LidarMounting(preset="hesai_pandar64", at=(1, 2, 3))
    assert forward(level.euler(level.at)) == pytest.approx([1, 0, 0])
    # from (-9, -9) the region's middle (0, 0) is north-east: +X along (1, 1)/sqrt(2)
    face = LidarMounting(preset="hesai_pandar64", mount="TL SW", pitch_deg=0, face_region=True)
    assert forward(face.euler((-9, -9, 6.4), (0.0, 0.0))) == pytest.approx(
        [math.sqrt(0.5), math.sqrt(0.5), 0], abs=1e-12)
    # the same pose a study's candidate on that spot has (study/candidates.pose_matrix)
    e = face.euler((-9, -9, 6.4), (0.0, 0.0))
    assert orientation_matrix(e[2], e[1], e[0]) == pytest.approx(
        pose_matrix((-9, -9, 6.4), 45.0, 0.0)[:3, :3], abs=1e-12)
    with pytest.raises(SceneError, match="InfraLOB"):
        face.euler((0, 0, 0), None)


@pytest.mark.parametrize("kwargs, match", [
    ({}, "--mount OBJECT or --at"),
    ({"mount": "TL SW", "at": (0, 0, 0)}, "one of them"),
    ({"at": (float("nan"), 0, 0)}, "finite"),
    ({"at": (0, 0)}, "three"),
    ({"at": (0, 0, 0), "pitch_deg": float("inf")}, "--pitch"),
    ({"at": (0, 0, 0), "pitch_deg": 95}, "between -90 and 90"),
    ({"at": (0, 0, 0), "yaw_deg": float("nan")}, "--yaw"),
    ({"at": (0, 0, 0), "yaw_deg": 10, "face_region": True}, "not both"),
    ({"at": (0, 0, 0), "name": ""}, "needs a name"),
    ({"at": (0, 0, 0), "name": "LiDAR "}, "spaces"),
    ({"at": (0, 0, 0), "name": "x" * 256}, "255"),
    ({"at": (0, 0, 0), "preset": " "}, "preset"),
])
def test_bad_mountings_refused(kwargs, match):
    kwargs = {"preset": "hesai_pandar64", **kwargs}
    with pytest.raises(SceneError, match=match):
        LidarMounting(**kwargs)


def test_positions_parsed_or_refused():
    assert parse_position("1,-2.5,6") == (1.0, -2.5, 6.0)
    for bad in ("nan,0,1", "1,inf,2", "1,2", "1,2,3,4", "a,b,c", ""):
        with pytest.raises(SceneError, match="--at"):
            parse_position(bad)
    # Blender keeps a location in 32-bit floats: a value it would move by more than
    # 1 mm is refused, one it holds within that (or exactly) is kept as given
    assert parse_position("20000.5,-8000.0001,123456.789") == (20000.5, -8000.0001, 123456.789)
    for bad, said in (("1,2,1e30", "would hold it as 1.0000000150474662e+30"),
                      ("1e39,0,0", "cannot hold it"), ("16777217,0,0", "would hold it as 16777216.0, 1 m away")):
        with pytest.raises(SceneError, match="--at: .* 32-bit floats, which " + re.escape(said)):
            parse_position(bad)
    assert check_name("é" * 127) == "é" * 127  # 254 bytes: Blender keeps it whole
    with pytest.raises(SceneError):
        check_name("é" * 128)
