"""Beam footprints and multiple returns (docs/realism.md): a box edge in front of a wall,
against the footprint's geometry; thin rays (no divergence, footprint off) unchanged to
the byte; seeded reproducibility."""

import hashlib
import math

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.physics.detection import DetectionModel
from rls_addon.core.errors import PresetError, SettingsError
from rls_addon.core.physics.depth_edges import neighbour_pairs
from rls_addon.core.physics.footprint import RING, Beam, ring_directions
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scene.geometry import MaterialInfo
from rls_addon.core.device.patterns.base import ScanPattern
from rls_addon.core.device.presets import (
    DevicePreset,
    RangeModel,
    get_preset,
    preset_from_dict,
)
from rls_addon.core.scan.settings import ScanSettings
from tests.core.scenes import box_geometry, merge

DIV = 0.00089          # the Mid-40's full divergence; the ring lies at half of it
W = DIV / 2.0
BOX_X, WALL_X = 20.0, 30.0   # box front face, wall 10 m behind it
BOX_LABEL, WALL_LABEL = 4, 7


def device(divergence=DIV, mode="strongest", figures=None, separation=1.0):
    beam = None if divergence is None else Beam((divergence, divergence), mode, separation)
    model = None if figures is None else DetectionModel(tuple(figures))
    return DevicePreset(id="t", name="t", family="custom", source="test", frequency_hz=10.0,
                        range=RangeModel(0.5, 600.0, 0.0), detection=model, beam=beam)


def edge_scene(gap=WALL_X - BOX_X):
    """A box whose side face ends at y = 0 (its vertical edge at azimuth 0 seen from the
    origin), covering y < 0, and a wall ``gap`` m behind its front face."""
    box = box_geometry((BOX_X, -10.0, -10.0), (BOX_X + 2.0, 0.0, 10.0), BOX_LABEL, 3, "box",
                       MaterialInfo("box", 0.5))
    wx = BOX_X + gap
    wall = box_geometry((wx, -20.0, -20.0), (wx + 1.0, 20.0, 20.0), WALL_LABEL, 5, "wall",
                        MaterialInfo("wall", 0.5))
    return merge(box, wall)


def grid(rows=600, cols=31, step_deg=0.2, seed=0):
    """A spinning-like pattern: ``rows`` channels within +-2 deg of the horizon, each a
    row of ``cols`` azimuths ``step_deg`` apart around 0 with a random offset per row
    (so the edge falls anywhere between two rays)."""
    rng = np.random.default_rng(seed)
    step = math.radians(step_deg)
    el = np.linspace(math.radians(-2.0), math.radians(2.0), rows)
    off = rng.uniform(0.0, step, rows)
    az = (np.arange(cols) - cols // 2)[None, :] * step + off[:, None]   # (rows, cols)
    el2 = np.broadcast_to(el[:, None], az.shape)
    # firing order: one column of every channel at a time
    az, el2 = az.T.ravel(), el2.T.ravel()
    d = np.c_[np.cos(el2) * np.cos(az), np.cos(el2) * np.sin(az), np.sin(el2)]
    ch = np.tile(np.arange(rows, dtype=np.uint16), cols)
    n = len(d)
    return ScanPattern(d, np.linspace(0.0, 0.099, n), ch, 0.1), az, el2


def scan(geometry, pattern, preset, **settings):
    settings.setdefault("noise", False)
    s = ScanSettings(seed=settings.pop("seed", 5), **settings)
    return scan_frame(geometry, pattern, np.eye(4), preset, s, caster_factory=NumpyCaster,
                      frame=0, sensor="t")


def straddling(az, el):
    """Rays whose cone (the ring at the 1/e^2 radius W) reaches across the box's edge
    (the plane y = 0): the horizontal ring point turns the ray by W about the vertical,
    which moves its azimuth by W / cos(el)."""
    return np.abs(az) < W / np.cos(el)


def sha(points):
    return hashlib.sha256(points.tobytes()).hexdigest()


# ---- the footprint's sampling -----------------------------------------------------------

def test_the_ring_lies_at_half_the_divergence():
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
    ring = ring_directions(d, (DIV, 2 * DIV))
    assert ring.shape == (2, RING, 3)
    np.testing.assert_allclose(np.linalg.norm(ring, axis=2), 1.0)
    ang = np.arccos(np.clip(np.einsum("ck,csk->cs", d, ring), -1, 1))
    # horizontal ring point at W, vertical ones (elliptical) up to 2W
    assert ang[0, 0] == pytest.approx(W, rel=1e-6)
    assert ang.max() <= 2 * W * (1 + 1e-6)
    # the first ring point is horizontal: it turns the ray about the vertical
    assert abs(ring[0, 0, 2]) < 1e-12


def test_neighbours_are_the_channel_rows_and_the_elevation_columns():
    pattern, _, _ = grid(rows=4, cols=3)
    a, b = neighbour_pairs(pattern)
    pairs = {(int(x), int(y)) for x, y in zip(a, b)}
    # channel 0's rays are 0, 4, 8; the elevation neighbour of ray 0 is ray 1
    assert (0, 4) in pairs and (4, 8) in pairs and (0, 1) in pairs
    assert len(pairs) == 4 * 2 + 3 * 3


# ---- dual returns at a box edge ------------------------------------------------------------

def test_dual_return_gives_two_echoes_where_the_cone_straddles_the_edge():
    pattern, az, el = grid()
    res = scan(edge_scene(), pattern, device(mode="dual"))
    pts = res.points
    ray = res.rays_cast  # not kept: use return_index / num_returns and ranges
    assert ray is None
    two = pts["num_returns"] == 2
    # every pulse with two echoes gives exactly two points: the box's, then the wall's
    assert np.all(pts["return_index"][two] == np.tile([1, 2], np.count_nonzero(two) // 2))
    near, far = pts[two][0::2], pts[two][1::2]
    assert np.all(near["label"] == BOX_LABEL) and np.all(far["label"] == WALL_LABEL)
    assert np.all(far["range"] - near["range"] > 9.0)
    # the pulses with two echoes are the rays whose cone straddles the edge
    want = straddling(az, el)
    assert np.count_nonzero(two) // 2 == np.count_nonzero(want)
    # and their directions are those rays' (the points' azimuths are within W of 0)
    got_az = np.arctan2(near["y"], near["x"])
    assert np.all(np.abs(got_az) < W / np.cos(np.radians(2.0)) + 1e-9)
    # elsewhere one echo: every other ray returns one point
    one = pts[~two]
    assert np.all(one["num_returns"] == 1) and np.all(one["return_index"] == 1)
    assert len(one) == len(az) - np.count_nonzero(want)
    assert res.stats["multi_echo_rays"] == np.count_nonzero(want)


def test_strongest_return_gives_one_point_per_pulse_and_edge_points_as_the_geometry_says():
    """With one return per pulse, the share of pulses that saw two echoes (edge points)
    is the share of rays whose cone straddles the edge; for rays evenly spread across
    the edge that is 2 W / (ray spacing) of the rays next to it: checked against the
    pattern's own rays exactly, and against the analytic 2 W / step within 4 sigma of
    the random row offsets."""
    rows, step = 1200, math.radians(0.2)
    pattern, az, el = grid(rows=rows)
    res = scan(edge_scene(), pattern, device(mode="strongest"))
    pts = res.points
    assert len(pts) == len(az)                       # one point per pulse
    edge = np.count_nonzero(pts["num_returns"] == 2)
    assert edge == np.count_nonzero(straddling(az, el))
    # analytic: per row, rays within W of the edge: 2 W / step on average (Bernoulli)
    p = 2 * W / step
    assert abs(edge / rows - p) <= 4 * math.sqrt(p * (1 - p) / rows), (edge / rows, p)
    # the strongest echo: the centre's surface carries half the energy plus its ring
    # points; the reported point is where most of the light came from
    e = pts[pts["num_returns"] == 2]
    assert set(np.unique(e["label"])) <= {BOX_LABEL, WALL_LABEL}
    # nearer and brighter: an edge ray's box echo (at 20 m) outshines the wall's (30 m)
    # unless the box holds less than (20/30)^2 of the light
    assert np.count_nonzero(e["label"] == BOX_LABEL) > 0


def test_last_return_reports_the_wall_behind_the_edge():
    pattern, az, el = grid(rows=200)
    res = scan(edge_scene(), pattern, device(mode="last"))
    pts = res.points
    e = pts[pts["num_returns"] == 2]
    assert len(e) == np.count_nonzero(straddling(az, el)) and len(e)
    assert np.all(e["label"] == WALL_LABEL) and np.all(e["return_index"] == 2)


def test_echoes_closer_than_the_separation_give_one_mixed_point_between_them():
    """A wall 0.3 m behind the box edge (less than the 1 m separation): the straddling
    rays report one point at the energy-weighted range, between the box and the wall."""
    pattern, az, el = grid(rows=400)
    res = scan(edge_scene(gap=0.3), pattern, device(mode="dual"))
    pts = res.points
    assert np.all(pts["num_returns"] == 1) and len(pts) == len(az)
    r_box = BOX_X / (np.cos(az) * np.cos(el))
    mixed = straddling(az, el)
    # points come in ray order: one per ray
    rng_ = pts["range"]
    between = (rng_ > r_box + 1e-3) & (rng_ < r_box + 0.3 / (np.cos(az) * np.cos(el)) - 1e-3)
    assert np.all(between[mixed]) and np.count_nonzero(mixed)
    assert np.count_nonzero(between) == np.count_nonzero(mixed)
    assert res.stats["mixed_points"] == np.count_nonzero(mixed)


def test_detection_applies_per_echo():
    """With the LiDAR equation, a faint echo (a ring point's 1/12 of the beam on a far
    wall) is lost where a full beam would be seen: fewer second echoes than without."""
    pattern, az, el = grid(rows=400)
    far = edge_scene(gap=150.0)      # the wall at 170 m
    figures = ((0.10, 90.0), (0.80, 260.0))
    with_model = scan(far, pattern, device(mode="dual", figures=figures))
    carla = scan(far, pattern, device(mode="dual"))
    two_model = np.count_nonzero(with_model.points["num_returns"] == 2)
    two_carla = np.count_nonzero(carla.points["num_returns"] == 2)
    assert two_carla // 2 == np.count_nonzero(straddling(az, el))
    assert two_model < two_carla


# ---- thin rays are what they were ------------------------------------------------------------

def test_zero_divergence_and_footprint_off_are_byte_identical_to_thin_rays():
    pattern, _, _ = grid(rows=200)
    g = edge_scene()
    thin = scan(g, pattern, device(divergence=None), noise=True, seed=3)
    zero = scan(g, pattern, device(divergence=0.0, mode="dual"), noise=True, seed=3)
    off = scan(g, pattern, device(mode="dual"), noise=True, seed=3, footprint="off")
    assert sha(thin.points) == sha(zero.points) == sha(off.points)
    assert "footprint_rays" not in zero.stats and "footprint_rays" not in off.stats
    assert np.all(thin.points["num_returns"] == 1) and np.all(thin.points["return_index"] == 1)
    # a return mode without a divergence changes nothing either
    dual = scan(g, pattern, device(divergence=None), noise=True, seed=3, return_mode="dual")
    assert sha(dual.points) == sha(thin.points)


def test_far_from_edges_the_footprint_changes_nothing():
    """Rays whose sub-rays agree with their centre keep their bytes: a wall alone."""
    pattern, _, _ = grid(rows=100)
    wall = box_geometry((30.0, -20.0, -20.0), (31.0, 20.0, 20.0), WALL_LABEL, 5, "wall")
    a = scan(wall, pattern, device(divergence=None), noise=True)
    b = scan(wall, pattern, device(mode="dual"), noise=True)
    assert sha(a.points) == sha(b.points)


def test_golden_presets_have_no_divergence():
    """The golden checksums' presets keep thin rays, so the default keeps their bytes."""
    for pid in ("hesai_pandar64", "generic_uniform32"):
        assert get_preset(pid).beam is None
    assert get_preset("livox_mid40").beam.divergence_rad == (DIV, DIV)


def test_seeded_reproducibility():
    pattern, _, _ = grid(rows=300)
    g = edge_scene(gap=150.0)
    figures = ((0.10, 90.0), (0.80, 260.0))
    runs = [scan(g, pattern, device(mode="dual", figures=figures), noise=True, seed=11)
            for _ in range(2)]
    other = scan(g, pattern, device(mode="dual", figures=figures), noise=True, seed=12)
    assert sha(runs[0].points) == sha(runs[1].points)
    assert sha(other.points) != sha(runs[0].points)


# ---- presets and settings --------------------------------------------------------------------

def _preset(beam):
    return {"id": "b", "name": "b", "family": "risley", "source": "t", "frequency_hz": 10.0,
            "range": {"max_m": 100.0}, "beam": beam,
            "scan": {"pulse_rate_hz": 1000.0, "rotation_hz": [10.0], "wedge_deg": [10.0],
                     "refractive_index": 1.5}}


def test_beam_tables():
    b = preset_from_dict(_preset({"divergence_rad": [0.001, 0.002], "return_mode": "dual",
                                  "echo_separation_m": 0.5})).beam
    assert b == Beam((0.001, 0.002), "dual", 0.5)
    assert preset_from_dict(_preset({"divergence_rad": 0.001})).beam.return_mode == "strongest"
    for bad, words in (({"divergence_rad": 0.5}, "must be <= 0.1"),
                       ({"return_mode": "first"}, "must be one of strongest, last, dual"),
                       ({"spot": 1}, "unknown key 'spot'")):
        with pytest.raises(PresetError, match="beam"):
            try:
                preset_from_dict(_preset(bad), "p.toml")
            except PresetError as exc:
                assert words in str(exc), str(exc)
                raise


def test_settings_check_the_choices():
    with pytest.raises(SettingsError, match="return mode"):
        ScanSettings(return_mode="first")
    with pytest.raises(SettingsError, match="footprint"):
        ScanSettings(footprint="on")
