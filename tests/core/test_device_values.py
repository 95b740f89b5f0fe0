"""A preset's values after a LiDAR's settings (``scan/device_values.py``): every override
applied in one place, and what the frame draws with is what the sidecar records."""

import dataclasses

import numpy as np
import pytest

from rls_addon.core.device.presets import get_preset
from rls_addon.core.errors import SettingsError
from rls_addon.core.scan.device_values import DeviceValues, device_values
from rls_addon.core.scan.run import ScanRun, SensorJob
from rls_addon.core.scan.settings import LidarSettings, ScanSettings

from .fakes import numpy_factory, small_preset, street


def test_the_presets_values_without_overrides():
    p = get_preset("velodyne_vlp16")
    v = device_values(p, ScanSettings())
    assert v.range_m == (p.range.min_m, p.range.max_m)
    assert v.noise_sigma_m == p.range.noise_sigma_m > 0
    assert v.attenuation_per_m == p.attenuation_per_m
    assert v.motion_tolerance_m == p.range.noise_sigma_m
    assert v.weather is None and v.beam is None


def test_every_override_is_applied():
    p = get_preset("livox_mid40")  # datasheet figures and a beam divergence
    s = ScanSettings(min_range_m=2.0, max_range_m=50.0, noise_sigma_m=0.05,
                     attenuation_per_m=0.01, motion_tolerance_m=0.003,
                     weather="fog:visibility=80", detection="carla", footprint="off")
    v = device_values(p, s)
    assert v.range_m == (2.0, 50.0) and v.noise_sigma_m == 0.05
    assert v.attenuation_per_m == 0.01 and v.motion_tolerance_m == 0.003
    assert v.detection is None and v.beam is None
    assert v.weather is not None and v.weather.alpha > 0
    on = device_values(p, ScanSettings())
    assert on.detection is not None and on.beam is not None


@pytest.mark.parametrize("kw,words", [
    (dict(min_range_m=150.0, max_range_m=100.0), r"minimum range \(150 m, the override\) "
                                                 r"must be below the maximum range \(100 m"),
    (dict(max_range_m=0.1), r"minimum range \(1 m, the preset's\).*\(0.1 m, the override\)"),
    (dict(min_range_m=200.0), r"\(200 m, the override\).*\(100 m, the preset's\)"),
    (dict(min_range_m=5.0, max_range_m=5.0), r"must be below"),
])
def test_a_range_override_that_keeps_no_return_is_refused(kw, words):
    """Min Range 150 m over Max Range 100 m scanned clouds of 0 points with exit 0."""
    p = get_preset("velodyne_vlp16")  # 1..100 m
    assert (p.range.min_m, p.range.max_m) == (1.0, 100.0)
    with pytest.raises(SettingsError, match=words):
        device_values(p, ScanSettings(**kw))


def test_noise_off_is_zero_sigma_and_the_tolerance_keeps_the_devices_noise():
    p = small_preset(noise=0.02)
    v = device_values(p, ScanSettings(noise=False, noise_sigma_m=0.5))
    assert v.noise_sigma_m == 0.0
    assert device_values(p, ScanSettings(noise_sigma_m=0.5)).motion_tolerance_m == 0.02
    assert device_values(small_preset(noise=0.0), ScanSettings()).motion_tolerance_m == 0.01


def test_a_run_resolves_each_sensors_device_once_and_passes_it_down(monkeypatch):
    """Issue 41: the values were worked out three times per scan (the session twice, the
    frame once, behind a process-wide cache) and the raw preset went down to the frame.
    A run resolves them once per sensor; the session's sub-steps and sidecar, and the
    frame, read those (the frame gets the values, not the preset)."""
    from rls_addon.core.scan import session

    resolved, given = [], []
    resolve = DeviceValues.resolve.__func__
    monkeypatch.setattr(DeviceValues, "resolve", classmethod(
        lambda cls, p, s: resolved.append(p.id) or resolve(cls, p, s)))
    frame = session.scan_frame_started
    monkeypatch.setattr(session, "scan_frame_started",
                        lambda scene, pattern, pose, device, *a, **k:
                        given.append(device) or frame(scene, pattern, pose, device, *a, **k))
    jobs = [SensorJob(name, LidarSettings(preset=p.id, scan=ScanSettings(
        motion="substeps", substeps=0, max_range_m=rmax)), p)
        for name, p, rmax in (("pole", small_preset(pid="a"), 40.0),
                              ("mast", small_preset(pid="b"), 50.0))]
    run = ScanRun(street(car_speed=8.0), jobs, [1, 2, 3], factory=numpy_factory).run()
    assert run.scanned == 6 and sorted(resolved) == ["a", "b"]
    assert len(given) == 6 and all(isinstance(d, DeviceValues) for d in given)
    assert {d.max_range_m for d in given} == {40.0, 50.0}
    effects = run.last[1]["effects"]
    # the moving car's sub-steps chosen against the device's tolerance
    assert effects["range_m"] == [0.3, 50.0] and effects["substeps_used"] > 1


def test_a_frame_given_the_values_or_the_preset_gives_the_same_points():
    """``scan_frame`` takes the values a session resolved, or a preset (scripts, tests)
    that it resolves itself: the same bytes."""
    from rls_addon.core.casting import NumpyCaster
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scene.instances import object_table, world_geometry

    p = small_preset(noise=0.02)
    p = dataclasses.replace(p, dropout=dataclasses.replace(p.dropout, general_rate=0.2))
    s = ScanSettings(seed=5, max_range_m=35.0)
    source = street()
    source.set_frame(1)
    read = source.read(np.zeros(3), 100.0, set())
    scene = world_geometry(read.instances, object_table(read.instances), read.materials)
    pose = source.sensor_pose("pole")
    values = device_values(p, s)
    assert values.dropout == p.dropout
    by_preset = scan_frame(scene, p.pattern(), pose, p, s, NumpyCaster).points
    by_values = scan_frame(scene, p.pattern(), pose, values, s, NumpyCaster).points
    assert len(by_values) > 100 and by_values.tobytes() == by_preset.tobytes()
    full = scan_frame(scene, p.pattern(), pose, p, dataclasses.replace(s, dropout=False),
                      NumpyCaster).points
    assert len(full) > len(by_values)  # the dropout the values carry was applied


def test_the_sidecar_records_the_noise_the_frame_drew_with():
    """The sidecar said the preset's sigma even when the LiDAR overrode it."""
    preset = small_preset(noise=0.02)
    got = {}
    for sigma in (None, 0.2):
        settings = LidarSettings(preset=preset.id, scan=ScanSettings(noise_sigma_m=sigma))
        ScanRun(street(), [SensorJob("pole", settings, preset)], [1], factory=numpy_factory,
                on_result=lambda j, f, r, i, key=sigma: got.update({key: (r, i)})).run()
    assert got[None][1]["effects"]["noise_sigma_m"] == 0.02
    assert got[0.2][1]["effects"]["noise_sigma_m"] == 0.2
    # the same rays with the same draws: each point moved along its ray by
    # (0.2 - 0.02) x its standard normal draw, |N(0, 1)| averaging sqrt(2 / pi)
    a, b = got[None][0].points, got[0.2][0].points
    assert len(a) == len(b) > 100
    moved = np.linalg.norm(np.stack([b[c] - a[c] for c in "xyz"], 1), axis=1)
    assert abs(moved.mean() / 0.18 - np.sqrt(2 / np.pi)) < 0.1
