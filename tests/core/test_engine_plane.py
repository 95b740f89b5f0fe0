"""Engine accuracy against analytic answers, with the exact numpy reference caster."""

import numpy as np
import pytest

from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.scene.geometry import MaterialInfo, ObjectInfo, SceneGeometry
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import DevicePreset, RangeModel
from rls_addon.core.casting import NumpyCaster

PRESET = DevicePreset(id="t", name="t", family="spinning", source="test", frequency_hz=10.0,
                      range=RangeModel(0.1, 100.0, 0.02))


def quad(x0, x1, y0, y1, z, obj=0):
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    t = np.array([[0, 1, 2], [0, 2, 3]])
    return v, t


def ground(z=-2.0, size=50.0, offset=(0.0, 0.0, 0.0)):
    v, t = quad(-size, size, -size, size, z)
    v = v + np.asarray(offset)
    return SceneGeometry(v, t, [0, 0], [0, 0], [ObjectInfo("ground", 1, 1)],
                         [MaterialInfo("asphalt", 0.3)])


def pose(origin=(0, 0, 0)):
    m = np.eye(4)
    m[:3, 3] = origin
    return m


def down_pattern():
    return spinning_pattern(np.linspace(-30, -5, 8), 10.0, 8 * 360 * 10)


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (1e5, -2e5, 30.0)])
def test_plane_ranges_exact(offset):
    g = ground(offset=offset)
    pat = down_pattern()
    res = scan_frame(g, pat, pose(offset), PRESET, ScanSettings(noise=False), NumpyCaster)
    p = res.points
    assert len(p) == len(pat)  # every downward ray hits the 100 m ground
    expected = 2.0 / -pat.directions[:, 2]  # points keep the pattern's order
    assert np.max(np.abs(p["range"] - expected)) <= 1e-4
    assert np.max(np.abs(p["z"] + 2.0)) <= 1e-4
    assert set(np.unique(p["label"])) == {1}
    assert set(np.unique(p["instance"])) == {1}


def test_same_inputs_identical_outputs_and_noise_seeded():
    g, pat = ground(), down_pattern()
    a = scan_frame(g, pat, pose(), PRESET, ScanSettings(seed=3), NumpyCaster).points
    b = scan_frame(g, pat, pose(), PRESET, ScanSettings(seed=3), NumpyCaster).points
    c = scan_frame(g, pat, pose(), PRESET, ScanSettings(seed=4), NumpyCaster).points
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a["range"], c["range"])
    exact = scan_frame(g, pat, pose(), PRESET, ScanSettings(noise=False), NumpyCaster).points
    err = a["range"] - exact["range"]
    assert abs(err.std() - 0.02) < 0.002


def test_min_range_blind_zone_and_max_range():
    g, pat = ground(z=-0.05), down_pattern()
    res = scan_frame(g, pat, pose(), PRESET, ScanSettings(noise=False, min_range_m=0.2,
                                                          max_range_m=0.3), NumpyCaster)
    assert len(res.points) > 0
    assert res.points["range"].min() >= 0.2 and res.points["range"].max() <= 0.3


def test_empty_scene_and_nothing_in_range_warn():
    pat = down_pattern()
    empty = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), int), [], [])
    res = scan_frame(empty, pat, pose(), PRESET, ScanSettings(), NumpyCaster)
    assert len(res.points) == 0 and "no geometry" in res.warnings[0]
    far = ground(offset=(0, 0, -500))
    res = scan_frame(far, pat, pose(), PRESET, ScanSettings(), NumpyCaster)
    assert len(res.points) == 0 and "within 100 m" in res.warnings[0]


def test_world_frame_matches_sensor_frame_transformed():
    g, pat = ground(), down_pattern()
    m = pose((1.0, 2.0, 0.5))
    ang = np.deg2rad(30)
    m[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
    s = scan_frame(g, pat, m, PRESET, ScanSettings(noise=False), NumpyCaster).points
    w = scan_frame(g, pat, m, PRESET, ScanSettings(noise=False, frame_space="world"),
                   NumpyCaster).points
    xyz_s = np.stack([s["x"], s["y"], s["z"]], 1)
    xyz_w = np.stack([w["x"], w["y"], w["z"]], 1)
    assert np.allclose(xyz_s @ m[:3, :3].T + m[:3, 3], xyz_w, atol=1e-9)
    assert np.allclose(w["z"], -2.0, atol=1e-9)


def test_range_noise_is_gaussian_with_the_given_sigma():
    """Box-Muller noise against the normal distribution's own numbers (n = 400,001:
    the statistical tolerances below are > 5 standard errors)."""
    from math import erf, sqrt

    from rls_addon.core.physics import effects

    sigma, n = 0.03, 400_001
    x = effects.range_noise(np.random.default_rng(5), n, sigma).astype(np.float64)
    assert x.shape == (n,) and np.isfinite(x).all()
    assert abs(x.mean()) < 5 * sigma / sqrt(n)
    assert abs(x.std() / sigma - 1) < 0.006
    for k in (1, 2, 3):  # share within k sigma
        assert abs(np.mean(np.abs(x) <= k * sigma) - erf(k / sqrt(2))) < 0.004
    z = x / sigma
    assert abs(np.mean(z ** 4) - 3.0) < 0.06  # Gaussian kurtosis
    h = n // 2  # the cosine and sine halves come from the same uniforms: independent
    assert abs(np.corrcoef(z[:h], z[h:2 * h])[0, 1]) < 0.01
    assert np.abs(z).max() <= 5.78  # tails bounded by the 24-bit uniforms
    rng = np.random.default_rng(5)
    before = rng.bit_generator.state
    assert not effects.range_noise(rng, 10, 0.0).any()
    assert rng.bit_generator.state == before  # no noise, no draws
