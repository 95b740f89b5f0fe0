"""MEMS patterns. Tolerances: rays per frame within 1 % of point rate x frame time;
M1 centre zone spans the published 25 deg vertically within 0.05 deg, the whole model
the published 120 deg horizontally within 3 deg (the PCSim model reaches 122.9 deg)."""

import numpy as np
import pytest

from rls_addon.core.errors import PatternError
from rls_addon.core.device.patterns.base import angles_from_directions
from rls_addon.core.device.patterns.mems import blickfeld_pattern, lissajous_zones_pattern
from rls_addon.core.device.presets import get_preset


def test_m1_rays_per_frame_follow_point_rate():
    p = get_preset("robosense_m1")
    assert len(p.pattern()) == pytest.approx(787_500 / p.frequency_hz, rel=0.01)


def test_m1_fov():
    pat = get_preset("robosense_m1").pattern()
    az, el = angles_from_directions(pat.directions)
    h = -np.degrees(az)
    assert np.ptp(h) == pytest.approx(120.0, abs=3.0)
    centre = pat.channels < 2  # zone 0, upper and lower band
    assert np.degrees(el[centre]).max() == pytest.approx(12.5, abs=0.05)
    assert np.degrees(el[centre]).min() == pytest.approx(-12.5, abs=0.05)
    assert np.ptp(h[centre]) == pytest.approx(25.0, abs=0.05)


def test_m1_zones_and_bands():
    pat = get_preset("robosense_m1").pattern()
    az, el = angles_from_directions(pat.directions)
    h = -np.degrees(az)
    assert sorted(set(pat.channels.tolist())) == list(range(10))
    for zone, centre in enumerate((0.0, -24.0, 24.0, -48.0, 48.0)):
        m = pat.channels // 2 == zone
        assert np.mean(h[m]) == pytest.approx(centre, abs=1.0)
    # upper band sits above the lower band in every zone
    for zone in range(5):
        up = np.degrees(el[pat.channels == 2 * zone]).mean()
        lo = np.degrees(el[pat.channels == 2 * zone + 1]).mean()
        assert up > lo


def test_timestamps_and_unit_vectors():
    pat = lissajous_zones_pattern(10.0, 787_500)
    assert np.all(np.diff(pat.times) >= 0)
    assert pat.times[0] == 0.0 and pat.times[-1] < pat.period
    assert np.allclose(np.linalg.norm(pat.directions, axis=1), 1.0)


def test_blickfeld_amplitude_ramps_over_frame():
    pat = blickfeld_pattern(10.0, 200_000, mirror_hz=150.0, h_fov_deg=70.0, v_fov_deg=30.0)
    assert len(pat) == 20_000
    az, el = angles_from_directions(pat.directions)
    el = np.abs(np.degrees(el))
    n = len(el)
    assert el[: n // 10].max() < 0.15 * 15.0
    assert el[-n // 10:].max() == pytest.approx(15.0, abs=0.5)
    assert np.ptp(np.degrees(az)) == pytest.approx(70.0, abs=0.1)


def test_bad_rates():
    with pytest.raises(PatternError):
        lissajous_zones_pattern(10.0, 0.0)
    with pytest.raises(PatternError):
        blickfeld_pattern(10.0, 1e12)
