"""A preset's values after a LiDAR's settings (``scan/device_values.py``): every override
applied in one place, and what the frame draws with is what the sidecar records."""

import dataclasses

import numpy as np

from rls_addon.core.device.presets import get_preset
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


def test_noise_off_is_zero_sigma_and_the_tolerance_keeps_the_devices_noise():
    p = small_preset(noise=0.02)
    v = device_values(p, ScanSettings(noise=False, noise_sigma_m=0.5))
    assert v.noise_sigma_m == 0.0
    assert device_values(p, ScanSettings(noise_sigma_m=0.5)).motion_tolerance_m == 0.02
    assert device_values(small_preset(noise=0.0), ScanSettings()).motion_tolerance_m == 0.01


def test_resolved_once_per_preset_and_settings():
    p, s = small_preset(noise=0.02), ScanSettings(max_range_m=30.0)
    assert device_values(p, s) is device_values(p, dataclasses.replace(s))
    assert device_values(p, s) is not device_values(p, ScanSettings(max_range_m=31.0))
    other = small_preset(noise=0.02)  # same id, another object: its own values
    assert device_values(other, s) == device_values(p, s)
    assert device_values(other, s) is not device_values(p, s)
    assert DeviceValues.resolve(p, s) == device_values(p, s)


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
