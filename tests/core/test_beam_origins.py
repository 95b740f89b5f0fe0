"""Beam origins (issue 32): rays cast from each beam's own origin.

Ouster: a scan of the shipped OS1-64 preset (beam-origin ring 12.163 mm) inside a box,
noise off, puts every point where Ouster's published equations put the return of the
same beam at the same encoder angle, to 0.1 mm. The equations (Ouster OS1 software user
guide, "Lidar Range Data To XYZ Lookup Table"; ouster-sdk ouster_core/src/xyzlut.cpp):

    theta_e = 2 pi (1 - col / W),  theta_a = -2 pi beam_azimuth / 360,
    phi = 2 pi beam_altitude / 360,  n = lidar_origin_to_beam_origin_mm
    x = (r - n) cos(theta_e + theta_a) cos(phi) + n cos(theta_e)
    y = (r - n) sin(theta_e + theta_a) cos(phi) + n sin(theta_e)
    z = (r - n) sin(phi)

Velodyne: the per-laser vertical and horizontal offsets of an HDL-64E calibration as
ros-drivers/velodyne rawdata.cc turns a distance into a point.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.device.calibration_import import import_calibration
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import get_preset, preset_from_dict
from rls_addon.core.errors import PresetError
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.world.bodies import PreparedScene
from tests.core.scenes import box_geometry

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "calibration"
HALF = 6.0  # the box around the sensor: its inner faces are the target planes


def _scan(preset, pose=None, space="sensor"):
    pose = np.eye(4) if pose is None else pose
    room = box_geometry((-HALF, -HALF, -HALF), (HALF, HALF, HALF), name="room")
    scene = PreparedScene(room, pose[:3, 3], preset.range.max_m, NumpyCaster)
    settings = ScanSettings(seed=1, frame_space=space, noise=False, dropout=False,
                            detection="carla", ghosting=False)
    return scan_frame(scene, preset.pattern(), pose, preset, settings).points


def _ouster_points(preset, pts, n=0.012163):
    """Where Ouster's equations put each point's return (``n``: the beam-origin ring,
    metres): the range r that puts the beam's point on the face the point lies on, then
    (x, y, z) of that r."""
    table = preset.table
    w = round(360.0 / preset.scan["horizontal_resolution_deg"])
    col = np.rint(pts["time"] * preset.frequency_hz * w).astype(np.int64)
    ring = pts["ring"].astype(np.int64)
    theta_e = 2.0 * np.pi * (1.0 - col / w)
    theta_a = -2.0 * np.pi * np.asarray(table.azimuth_offsets_deg)[ring] / 360.0
    phi = 2.0 * np.pi * np.asarray(table.elevations_deg)[ring] / 360.0
    d = np.stack([np.cos(theta_e + theta_a) * np.cos(phi),
                  np.sin(theta_e + theta_a) * np.cos(phi), np.sin(phi)], axis=1)
    o = np.stack([n * np.cos(theta_e), n * np.sin(theta_e), np.zeros_like(theta_e)], axis=1)
    xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float64)
    axis = np.argmax(np.abs(xyz), axis=1)  # the face each point is on
    k = np.arange(len(xyz))
    face = np.sign(xyz[k, axis]) * HALF
    # x = (r - n) d + o on the face: (r - n) = (face - o) / d along that axis
    r = (face - o[k, axis]) / d[k, axis] + n
    return (r - n)[:, None] * d + o, r


def test_ouster_points_where_the_vendor_equations_put_them():
    preset = get_preset("ouster_os1_64")
    assert preset.scan["beam_origins_m"] == [[0.012163, 0.0, 0.0]]
    pts = _scan(preset)
    assert len(pts) == len(preset.pattern())  # every beam returns from the box
    want, r = _ouster_points(preset, pts)
    got = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float64)
    # the points are float32: 6 m carries ~0.5 um of rounding
    assert np.abs(got - want).max() < 1e-4
    # RLS's range is the distance from the beam's origin: Ouster's r less n
    np.testing.assert_allclose(pts["range"], r - 0.012163, rtol=0, atol=1e-4)
    # the test can fail: cast from the sensor origin, points are millimetres off
    plain = dataclasses.replace(preset, scan={k: v for k, v in preset.scan.items()
                                              if k != "beam_origins_m"})
    off = np.stack([(p := _scan(plain))["x"], p["y"], p["z"]], axis=1).astype(np.float64)
    assert np.abs(off - _ouster_points(plain, p)[0]).max() > 2e-3


def test_world_frame_points_move_with_the_sensor():
    preset = get_preset("ouster_os1_64")
    pose = np.eye(4)
    c, s = np.cos(0.7), np.sin(0.7)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = (0.4, -0.2, 0.3)
    sensor = _scan(preset, pose, "sensor")
    world = _scan(preset, pose, "world")
    a = np.stack([sensor["x"], sensor["y"], sensor["z"]], axis=1).astype(np.float64)
    b = np.stack([world["x"], world["y"], world["z"]], axis=1).astype(np.float64)
    np.testing.assert_allclose(a @ pose[:3, :3].T + pose[:3, 3], b, rtol=0, atol=2e-5)


def test_a_subset_of_rays_gets_its_own_origins():
    preset = get_preset("ouster_os1_64")
    room = box_geometry((-HALF, -HALF, -HALF), (HALF, HALF, HALF), name="room")
    scene = PreparedScene(room, np.zeros(3), preset.range.max_m, NumpyCaster)
    settings = ScanSettings(seed=1, noise=False, dropout=False, detection="carla", footprint="off")
    full = scan_frame(scene, preset.pattern(), np.eye(4), preset, settings).points
    rows = np.arange(5, len(preset.pattern()), 997)
    part = scan_frame(scene, preset.pattern(), np.eye(4), preset, settings, rays=rows).points
    for f in "xyz":
        np.testing.assert_array_equal(part[f], full[f][rows])


def _rawdata_point(distance, rotation_rad, laser):
    """ros-drivers/velodyne velodyne_pointcloud/src/lib/rawdata.cc (unpack): a distance
    at encoder ``rotation_rad`` (clockwise) to (x, y, z) in the ROS frame."""
    rot, vert = laser["rot_correction"], laser["vert_correction"]
    v, h = laser.get("vert_offset_correction", 0.0), laser.get("horiz_offset_correction", 0.0)
    cos_rot = math.cos(rotation_rad - rot)
    sin_rot = math.sin(rotation_rad - rot)
    xy = distance * math.cos(vert) - v * math.sin(vert)
    xx = xy * sin_rot - h * cos_rot
    yy = xy * cos_rot + h * sin_rot
    z = distance * math.sin(vert) + v * math.cos(vert)
    return np.array([yy, -xx, z])


def test_velodyne_offsets_as_rawdata_cc(tmp_path):
    import yaml

    name = "nebula_hdl64e_s3.yaml"
    p = import_calibration(FIX / name, "velodyne_hdl64e", "hdl64_unit", tmp_path)
    lasers = sorted(yaml.safe_load((FIX / name).read_text())["lasers"],
                    key=lambda d: d["laser_id"])
    pat = p.pattern()
    assert pat.origins is not None
    for k in range(0, len(pat), 997):
        laser = lasers[pat.channels[k]]
        head = -2.0 * np.pi * p.frequency_hz * pat.times[k]  # ccw; the encoder turns cw
        for distance in (2.0, 40.0):
            want = _rawdata_point(distance, -head, laser)
            got = pat.origins[k] + distance * pat.directions[k]
            assert np.abs(got - want).max() < 1e-9, (k, got, want)


def test_presets_without_origins_have_none():
    assert get_preset("velodyne_vlp32c").pattern().origins is None
    assert get_preset("hesai_pandar64").pattern().origins is None
    pat = get_preset("ouster_os1_128").pattern()
    assert np.allclose(np.linalg.norm(pat.origins[:, :2], axis=1), 0.015806)


def test_a_ring_origin_turns_with_the_head():
    pat = spinning_pattern([0.0, 10.0], 10.0, horizontal_resolution_deg=90.0,
                           origins_head_m=[[0.01, 0.0, 0.002]])
    np.testing.assert_allclose(pat.origins[::2], [[0.01, 0, 0.002], [0, -0.01, 0.002],
                                                  [-0.01, 0, 0.002], [0, 0.01, 0.002]],
                               atol=1e-15)
    turned = pat.started_at(90.0)
    np.testing.assert_allclose(turned.origins[0], [0.0, 0.01, 0.002], atol=1e-15)


@pytest.mark.parametrize("value,msg", [
    ([0.01, 0.0, 0.0], "must be a list of \\[x, y, z\\]"),
    ([[0.01, 0.0]], "must have 3 entries"),
    ([[2.0, 0.0, 0.0]], "must be <= 1.0"),
    ([[0.0, 0.0, 0.0]] * 3, "one for every beam or one per channel \\(2\\)"),
])
def test_beam_origins_key_is_validated(value, msg):
    data = {"id": "x", "name": "x", "family": "spinning", "source": "test", "frequency_hz": 10,
            "range": {"max_m": 50}, "scan": {"elevations_deg": [0.0, 1.0],
                                             "horizontal_resolution_deg": 1.0,
                                             "beam_origins_m": value}}
    with pytest.raises(PresetError, match=msg):
        preset_from_dict(data)


def test_a_still_sensor_with_beam_origins_reuses_its_static_cast():
    preset = get_preset("ouster_os1_64")
    room = box_geometry((-HALF, -HALF, -HALF), (HALF, HALF, HALF), name="room")
    pose = np.eye(4)
    pose[:3, 3] = (0.3, 0.1, -0.2)
    scene = PreparedScene(room, pose[:3, 3], preset.range.max_m, NumpyCaster)
    settings = ScanSettings(seed=1, noise=False, dropout=False, detection="carla")
    a = scan_frame(scene, preset.pattern(), pose, preset, settings, frame=0)
    b = scan_frame(scene, preset.pattern(), pose, preset, settings, frame=1)
    assert not a.stats["static_cast_reused"] and b.stats["static_cast_reused"]
    np.testing.assert_array_equal(a.points, b.points)
    turned = pose.copy()
    turned[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    c = scan_frame(scene, preset.pattern(), turned, preset, settings, frame=2)
    assert not c.stats["static_cast_reused"]
    assert not np.array_equal(c.points["range"], a.points["range"])


def test_the_vlp16_beams_leave_where_the_manual_puts_its_lasers():
    """VLP-16 user manual, Table 9-1: each laser sits a 'vertical correction' from the
    sensor origin (11.2 mm for laser 0 at -15 degrees down to -11.2 mm for laser 15 at
    +15), applied as ros-drivers' rawdata.cc does: across the beam, in its vertical
    plane; a point d along a beam is d * direction + that offset."""
    manual_mm = [11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2,
                 -9.7, 0.7, -11.2]
    pat = get_preset("velodyne_vlp16").pattern()
    v = np.array(manual_mm)[pat.channels] * 1e-3
    w = np.arcsin(np.clip(pat.directions[:, 2], -1.0, 1.0))
    np.testing.assert_allclose(pat.origins[:, 2], v * np.cos(w), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(pat.origins, axis=1), np.abs(v), rtol=0, atol=1e-9)
    # across the beam: the offset never moves a point along it
    assert np.abs(np.einsum("ij,ij->i", pat.origins, pat.directions)).max() < 1e-12
