"""Risley prisms (exact vector Snell refraction). Tolerances: Mid-40 / Mid-70 full cone
within 0.5 deg of 38.4 / 70.4; Avia and fitted models' FOV within 1 deg of the published
values over 1 s; rays per frame within 1 % of the point rate."""

import numpy as np
import pytest

from rls_addon.core.errors import PatternError
from rls_addon.core.device.patterns.base import angles_from_directions
from rls_addon.core.device.patterns.risley import cone_angle_deg, refract, risley_pattern
from rls_addon.core.device.presets import get_preset


def one_second(pid):
    s = get_preset(pid).scan
    return risley_pattern(10.0, s["pulse_rate_hz"], s["rotation_hz"], s["wedge_deg"],
                          s["refractive_index"], s.get("fan_deg", [0.0]), s.get("phase_deg"),
                          duration_s=1.0)


def test_refraction_obeys_snell():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(100, 3))
    d[:, 2] = np.abs(d[:, 2]) + 2.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.array([0.0, 0.0, -1.0])
    t = refract(d, n, 1 / 1.5)
    sin_i = np.linalg.norm(np.cross(d, n), axis=1)
    sin_t = np.linalg.norm(np.cross(t, n), axis=1)
    assert np.allclose(sin_i, 1.5 * sin_t)
    assert np.allclose(np.linalg.norm(t, axis=1), 1.0)
    with pytest.raises(PatternError, match="total internal reflection"):
        refract(np.array([[0.8, 0.0, 0.6]]), n, 1.5)


@pytest.mark.parametrize("pid,cone", [("livox_mid40", 38.4), ("livox_mid70", 70.4)])
def test_full_cone_angle(pid, cone):
    assert cone_angle_deg(one_second(pid).directions) == pytest.approx(cone, abs=0.5)


@pytest.mark.parametrize("pid,h,v", [
    ("livox_avia", 70.4, 77.2),
    ("livox_horizon", 81.7, 25.1),   # fitted
    ("livox_tele15", 14.5, 16.2),    # fitted
    ("livox_hap", 120.0, 25.0),      # fitted
])
def test_fov_matches_published(pid, h, v):
    az, el = angles_from_directions(one_second(pid).directions)
    assert np.degrees(np.ptp(az)) == pytest.approx(h, abs=1.0)
    assert np.degrees(np.ptp(el)) == pytest.approx(v, abs=1.0)


@pytest.mark.parametrize("pid,pps,beams", [
    ("livox_mid40", 100_000, 1), ("livox_mid70", 100_000, 1), ("livox_avia", 240_000, 6),
    ("livox_horizon", 240_000, 6), ("livox_tele15", 240_000, 6), ("livox_hap", 452_000, 6),
])
def test_rays_per_frame_and_times(pid, pps, beams):
    p = get_preset(pid)
    pat = p.pattern()
    assert len(pat) == pytest.approx(pps / p.frequency_hz, rel=0.01)
    assert len(set(pat.channels.tolist())) == beams
    assert np.all(np.diff(pat.times) >= 0)
    assert pat.times[0] == 0.0 and pat.period - 1e-4 < pat.times[-1] < pat.period


@pytest.mark.parametrize("pid", ["livox_mid40", "livox_mid70", "livox_avia"])
def test_pattern_does_not_repeat_within_one_second(pid):
    p = get_preset(pid)
    first = p.pattern(0).directions
    for k in range(1, 10):
        other = p.pattern(k).directions
        sep = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", first, other), -1, 1)))
        assert np.median(sep) > 1.0, f"frame {k} repeats frame 0"


@pytest.mark.parametrize("pid", ["livox_mid40", "livox_mid70", "livox_avia", "livox_horizon"])
def test_coverage_grows_with_integration_time(pid):
    pat = one_second(pid)
    az, el = angles_from_directions(pat.directions)
    cell = np.floor(np.degrees(np.stack([az, el], axis=1)) / 0.5).astype(int)
    counts = []
    for t in (0.1, 0.2, 0.5, 1.0):
        m = pat.times < t
        counts.append(len(np.unique(cell[m], axis=0)))
    assert all(b > a for a, b in zip(counts, counts[1:])), counts
    if pid != "livox_horizon":  # the fitted line scanner already fills ~80 % in 0.1 s
        assert counts[-1] > 1.5 * counts[0], counts


def test_frames_continue_the_rotation():
    p = get_preset("livox_mid40")
    span = one_second("livox_mid40")
    f3 = p.pattern(3)
    m = (span.times >= 0.3 - 1e-12) & (span.times < 0.4 - 1e-12)
    assert np.allclose(span.directions[m], f3.directions)


def test_fitted_presets_say_so():
    for pid in ("livox_horizon", "livox_tele15", "livox_hap"):
        p = get_preset(pid)
        assert p.fitted and "FITTED" in p.source
    for pid in ("livox_mid40", "livox_mid70", "livox_avia"):
        assert not get_preset(pid).fitted
