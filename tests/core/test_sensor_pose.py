"""The sensor frame of a LiDAR object whose matrix is not a plain rotation (mirrored,
scaled, degenerate): what it looks along, and that the sidecar's poses map its
sensor-frame points onto the world-frame points of the same scan."""

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.errors import SceneError
from rls_addon.core.output.io.sidecar import points_to_world
from rls_addon.core.points import xyz
from rls_addon.core.scan.aim import sensor_frame
from rls_addon.core.scan.frame import sensor_axes
from rls_addon.core.scan.session import ScanSession
from rls_addon.core.scan.settings import ScanSettings

from .fakes import small_preset, street

PRESET = small_preset()


def yawed(yaw_deg, scale=(1.0, 1.0, 1.0), at=(0.0, 0.0, 0.5)):
    a = np.deg2rad(yaw_deg)
    m = np.eye(4)
    m[:3, :3] = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]) \
        @ np.diag(scale)
    m[:3, 3] = at
    return m


def scan_both(scene, sensor, classes=None):
    """The same frame in the sensor and in the world frame: (sensor points, world points,
    the sensor-frame scan's sidecar info)."""
    out = []
    for space in ("sensor", "world"):
        result, info = ScanSession(NumpyCaster).scan(
            scene, sensor, PRESET, ScanSettings(seed=5, frame_space=space), 1, classes)
        out.append((result.points, info))
    (sensor_pts, info), (world_pts, _) = out
    assert len(sensor_pts) == len(world_pts) > 500
    return sensor_pts, world_pts, info


def mirrored(axis):
    s = [1.0, 1.0, 1.0]
    s[axis] = -1.0
    return tuple(s)


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
def test_a_still_mirrored_sensor_frame_maps_onto_its_world_frame(axis):
    scene = street()
    scene.sensors["pole"] = lambda s: yawed(30.0, mirrored(axis))
    sensor_pts, world_pts, info = scan_both(scene, "pole", classes=[11])
    back = xyz(points_to_world(sensor_pts, info))
    assert np.abs(back - xyz(world_pts)).max() <= 1e-6
    pose = np.asarray(info["sensor_to_world"])
    assert np.allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-12)
    assert np.linalg.det(pose[:3, :3]) > 0
    assert np.array_equal(info["sensor_pose_start"], info["sensor_to_world"])
    # the ground truth's boxes in the sensor frame: through the same pose
    assert info["objects"]
    for o in info["objects"]:
        centre = np.asarray(o["world"]["centre"])
        assert np.allclose(pose[:3, :3] @ o["sensor"]["centre"] + pose[:3, 3], centre)


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
def test_a_moving_mirrored_sensor_frame_maps_onto_its_world_frame(axis):
    scene = street()
    scene.moving_sensors = {"pole"}
    # driving and turning: a pose per firing time, from the sidecar's knots
    scene.sensors["pole"] = lambda s: yawed(200.0 * s, mirrored(axis), (6.0 * s, 0.0, 0.5))
    sensor_pts, world_pts, info = scan_both(scene, "pole")
    assert info["sensor_moves"]
    back = xyz(points_to_world(sensor_pts, info))
    assert np.abs(back - xyz(world_pts)).max() <= 1e-6
    for m in info["sensor_poses"]["matrices"]:
        r = np.asarray(m)[:3, :3]
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-12) and np.linalg.det(r) > 0


def test_a_scaled_sensor_frame_maps_onto_its_world_frame():
    scene = street()
    scene.sensors["pole"] = lambda s: yawed(-40.0, (2.0, 0.5, 3.0))
    sensor_pts, world_pts, info = scan_both(scene, "pole")
    assert np.abs(xyz(points_to_world(sensor_pts, info)) - xyz(world_pts)).max() <= 1e-6


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
@pytest.mark.parametrize("stretch", [(1.0, 1.0, 1.0), (1.0, 2.0, 3.0), (3.0, 0.5, 1.5)],
                         ids=["uniform", "stretched", "other"])
def test_a_mirrored_sensor_looks_along_its_own_x_with_its_own_z_up(axis, stretch):
    """The mirror flips the sensor's +Y (left) only: forward and up are the object's
    own +X and +Z, whichever axis its scale mirrors and however it is turned."""
    rng = np.random.default_rng(axis)
    for _ in range(20):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        m = np.eye(4)
        m[:3, :3] = q @ np.diag(np.multiply(mirrored(axis), stretch))
        m[:3, 3] = rng.normal(size=3)
        origin, rot = sensor_axes(m)
        cols = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
        assert np.allclose(origin, m[:3, 3])
        assert np.allclose(rot.T @ rot, np.eye(3), atol=1e-12) and np.linalg.det(rot) > 0
        assert np.allclose(rot[:, 0], cols[:, 0], atol=1e-9)
        assert np.allclose(rot[:, 2], cols[:, 2], atol=1e-9)
        assert np.allclose(rot[:, 1], -cols[:, 1], atol=1e-9)


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
def test_a_lidar_with_zero_scale_is_one_scene_error_naming_it(axis):
    scene = street()
    s = [1.0, 1.0, 1.0]
    s[axis] = 0.0
    scene.sensors["pole"] = lambda t: yawed(10.0, tuple(s))
    with pytest.raises(SceneError) as err:
        ScanSession(NumpyCaster).scan(scene, "pole", PRESET, ScanSettings(), 1, [11])
    assert str(err.value).startswith("LiDAR 'pole' has zero scale on an axis: ")


def test_a_moving_lidar_whose_scale_reaches_zero_is_one_scene_error_naming_it():
    scene = street()
    scene.moving_sensors = {"pole"}
    # scale 1 at the sweep's start, 0 at its end
    scene.sensors["pole"] = lambda t: yawed(0.0, (1.0, 1.0, max(0.0, 1.0 - 10.0 * t)))
    with pytest.raises(SceneError) as err:
        ScanSession(NumpyCaster).scan(scene, "pole", PRESET, ScanSettings(), 1)
    assert str(err.value).startswith("LiDAR 'pole' has zero scale on an axis: ")


def test_a_sheared_lidar_is_one_scene_error_naming_it():
    """A LiDAR turned under a parent scaled unevenly has axes not at right angles in
    the world (an audit measured its scan 26 degrees off its drawn +X): no one sensor
    frame, so it is refused, still or moving; scaled along its own axes or mirrored, it
    is not (above)."""
    turned = yawed(30.0, (1.0, 1.0, 1.0))
    parent = np.diag([3.0, 1.0, 1.0, 1.0])  # an uneven scale along the world's x
    scene = street()
    scene.sensors["pole"] = lambda t: parent @ turned
    with pytest.raises(SceneError) as err:
        ScanSession(NumpyCaster).scan(scene, "pole", PRESET, ScanSettings(), 1, [11])
    assert str(err.value).startswith("LiDAR 'pole' is sheared: its axes are not at right "
                                     "angles in the world (X-Y ")
    assert "Apply > Scale" in str(err.value)
    # a shear that grows over a moving LiDAR's sweep is caught too
    scene = street()
    scene.moving_sensors = {"pole"}
    scene.sensors["pole"] = lambda t: np.diag([1.0 + 20.0 * t, 1.0, 1.0, 1.0]) @ turned
    with pytest.raises(SceneError, match="LiDAR 'pole' is sheared"):
        ScanSession(NumpyCaster).scan(scene, "pole", PRESET, ScanSettings(), 1)
    # a shear far below a degree's hundredth (float32 rounding) is no shear
    almost = turned.copy()
    almost[:3, 0] += 1e-6
    assert np.isfinite(sensor_frame(almost, "pole")).all()
