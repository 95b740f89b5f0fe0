"""Boxes between a sensor's (or level) frame and the world, checked against
hand-computed cases and against what RLS's writers put in labels."""

import math

import numpy as np

from rls_addon.core.output.datasets.common import heading_in, level_frame
from rls_addon.core.evaluate.box_frames import frame_heading, to_frame, to_world

from .builders import pose

C30, S30 = math.cos(math.radians(30)), math.sin(math.radians(30))


def test_level_frame_yawed_90_degrees():
    m = pose(10.0, 5.0, 2.0, yaw=math.pi / 2)
    out = to_world([[3.0, 0.0, -1.0, 4.0, 2.0, 1.5, 0.2]], m)
    np.testing.assert_allclose(out, [[10.0, 8.0, 1.0, 4.0, 2.0, 1.5, 0.2 + math.pi / 2]],
                               atol=1e-12)


def test_pitched_sensor_box_across_its_view():
    """Sensor 5 m up, pitched 30 deg down: a box 10 m ahead at z 1 lying along world +Y
    is at (10 c + 4 s, 0, 10 s - 4 c) in the sensor frame with heading 90 deg."""
    m = pose(0.0, 0.0, 5.0, pitch=math.radians(30))
    local = [[10 * C30 + 4 * S30, 0.0, 10 * S30 - 4 * C30, 4.0, 2.0, 1.5, math.pi / 2]]
    np.testing.assert_allclose(to_world(local, m), [[10.0, 0.0, 1.0, 4.0, 2.0, 1.5,
                                                     math.pi / 2]], atol=1e-12)


def test_pitched_sensor_diagonal_box_heading_is_its_azimuth_in_the_sensor_frame():
    """A world box at yaw 45 deg shows heading atan2(1, cos 30) in the 30-deg-pitched
    frame (its length axis (c45, s45, 0) is (c30 c45, s45, s30 c45) there); reading it
    back gives 45 deg, where simply turning (cos h, sin h, 0) by the sensor would not."""
    m = pose(0.0, 0.0, 5.0, pitch=math.radians(30))
    h = math.atan2(1.0, C30)
    assert abs(frame_heading(m, [math.pi / 4])[0] - h) < 1e-12
    assert abs(to_world([[1, 0, 0, 4, 2, 1.5, h]], m)[0, 6] - math.pi / 4) < 1e-12
    naive = m[:3, :3] @ [math.cos(h), math.sin(h), 0.0]
    assert abs(math.atan2(naive[1], naive[0]) - math.pi / 4) > 0.05


def test_yawed_pitched_rolled_sensor_agrees_with_rls_labels():
    """frame_heading is what the kitti writer labels (heading_in of the box's world
    rotation), and to_world inverts it, level or not."""
    m = pose(2.0, -1.0, 6.0, yaw=0.7, pitch=math.radians(14), roll=math.radians(4))
    rng = np.random.default_rng(3)
    world = np.c_[rng.uniform(-30, 30, (20, 2)), rng.uniform(0, 2, 20),
                  rng.uniform(0.5, 5, (20, 3)), rng.uniform(-math.pi, math.pi, 20)]
    for frame in (m, level_frame(m)):
        labels = [heading_in(frame, pose(yaw=y)[:3, :3]) for y in world[:, 6]]
        local = to_frame(world, frame)
        np.testing.assert_allclose(local[:, 6], labels, atol=1e-12)
        back = to_world(local, frame)
        np.testing.assert_allclose(back[:, :6], world[:, :6], atol=1e-9)
        np.testing.assert_allclose(np.angle(np.exp(1j * (back[:, 6] - world[:, 6]))), 0,
                                   atol=1e-12)
