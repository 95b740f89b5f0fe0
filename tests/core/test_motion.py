"""Motion distortion against analytic answers (exact numpy caster)."""

import numpy as np
import pytest

from rls_addon.core.world.bodies import PreparedScene, RigidBody
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.scene.geometry import SceneGeometry
from rls_addon.core.scene.motion import Track, effective_times
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import DevicePreset, RangeModel
from rls_addon.core.casting import NumpyCaster

from .scenes import box_geometry, box_sdf

PRESET = DevicePreset(id="t", name="t", family="spinning", source="test", frequency_hz=10.0,
                      range=RangeModel(0.1, 100.0, 0.0))
EXACT = ScanSettings(noise=False, dropout=False, frame_space="world", ghosting=False)
V = 20.0  # m/s
T = 0.1   # s, a 10 Hz sweep


def pattern():
    # 8 channels around the horizon, 0.1 deg steps: 28,800 rays over one 0.1 s sweep.
    return spinning_pattern(np.linspace(-3, 3, 8), 10.0, 8 * 3600 * 10)


def translation(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def empty():
    return SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), int), [], [])


def moving_box_scan(settings):
    """A 4 x 2 x 2 m box 10 m ahead (+X), driving along +Y at 20 m/s."""
    local = box_geometry((-1, -2, -1), (1, 2, 1), label=11, instance=7)
    start = np.array([10.0, -6.0, 0.0])  # the sensor sees the front and the +Y side
    track = Track([0.0, T], [translation(*start), translation(*(start + [0, V * T, 0]))])
    body = RigidBody(local, track, NumpyCaster)
    static = PreparedScene(empty(), np.zeros(3), 100.0, NumpyCaster)
    res = scan_frame(static, pattern(), np.eye(4), PRESET, settings, moving=[body])
    return res, start


def test_track_interpolates_rotation_and_translation_exactly():
    ang = np.deg2rad(80)
    m1 = translation(4, -2, 1)
    m1[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
    tr = Track([0.0, 1.0], [np.eye(4), m1])
    mid = tr.at([0.5])[0]
    half = ang / 2
    assert np.allclose(mid[:3, :3], [[np.cos(half), -np.sin(half), 0],
                                     [np.sin(half), np.cos(half), 0], [0, 0, 1]], atol=1e-12)
    assert np.allclose(mid[:3, 3], [2, -1, 0.5])
    assert np.allclose(tr.at([1.0])[0], m1) and np.allclose(tr.at([0.0])[0], np.eye(4))


def test_moving_box_exact_every_point_on_the_box_at_its_own_time():
    res, start = moving_box_scan(EXACT)
    p = res.points
    assert len(p) > 300 and set(np.unique(p["label"])) == {11}
    xyz = np.stack([p["x"], p["y"], p["z"]], 1)
    centre = start + np.outer(p["time"], [0, V, 0])
    err = np.abs(box_sdf(xyz, centre, np.array([1, 2, 1])))
    assert err.max() <= 1e-3
    # ... and not on the box where it stood at the start of the sweep (distortion is real).
    frozen = np.abs(box_sdf(xyz, start, np.array([1, 2, 1])))
    assert frozen.max() > 0.1  # the box passes the beam about 9 ms into the sweep


@pytest.mark.parametrize("n", [1, 2, 4, 8])
def test_moving_box_substeps_within_half_step_bound(n):
    res, start = moving_box_scan(ScanSettings(noise=False, dropout=False, frame_space="world",
                                              ghosting=False, motion="substeps", substeps=n))
    p = res.points
    xyz = np.stack([p["x"], p["y"], p["z"]], 1)
    centre = start + np.outer(p["time"], [0, V, 0])
    err = np.abs(box_sdf(xyz, centre, np.array([1, 2, 1])))
    # A point can only be off along the motion (y); its y error is bounded by v*T/(2N).
    bound = V * T / (2 * n)
    assert err.max() <= bound + 1e-6
    if n <= 2:
        assert err.max() > 0.25 * bound  # the bound is approached, the test can fail


def test_snapshot_freezes_the_scene_at_the_sweep_start():
    res, start = moving_box_scan(ScanSettings(noise=False, dropout=False, frame_space="world",
                                              ghosting=False, motion="snapshot"))
    p = res.points
    xyz = np.stack([p["x"], p["y"], p["z"]], 1)
    assert np.abs(box_sdf(xyz, start, np.array([1, 2, 1]))).max() <= 1e-6


def test_effective_times():
    t = np.array([0.0, 0.024, 0.026, 0.099])
    assert np.allclose(effective_times(t, 0.1, "substeps", 4), [0.0125, 0.0125, 0.0375, 0.0875])
    assert np.allclose(effective_times(t, 0.1, "snapshot", 0), 0)
    assert np.array_equal(effective_times(t, 0.1, "exact", 0), t)


def test_moving_sensor_in_static_room_exact_against_analytic_pose():
    """A sensor driving at 10 m/s and yawing 90 deg/s inside a 20 x 12 x 6 m room."""
    room = box_geometry((-10, -6, -1), (10, 6, 5))
    w = np.deg2rad(90.0)

    def pose(t):
        m = translation(-2 + 10 * t, 0.5, 1.5)
        a = w * t
        m[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
        return m

    times = np.linspace(0, T, 65)
    track = Track(times, [pose(t) for t in times])
    pat = pattern()
    res = scan_frame(room, pat, pose(0), PRESET, EXACT, NumpyCaster, sensor_track=track)
    p = res.points
    assert len(p) == len(pat)  # a closed room: every ray returns
    t = p["time"]
    origin = np.stack([-2 + 10 * t, np.full_like(t, 0.5), np.full_like(t, 1.5)], 1)
    a = w * t
    d_s = pat.directions
    d = np.stack([np.cos(a) * d_s[:, 0] - np.sin(a) * d_s[:, 1],
                  np.sin(a) * d_s[:, 0] + np.cos(a) * d_s[:, 1], d_s[:, 2]], 1)
    # Analytic range: distance to the first of the six room planes along d.
    lo, hi = np.array([-10, -6, -1]), np.array([10, 6, 5])
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = np.where(d > 0, (hi - origin) / d, np.where(d < 0, (lo - origin) / d, np.inf))
    expected = tt.min(axis=1)
    xyz = np.stack([p["x"], p["y"], p["z"]], 1)
    # Interpolated rotation between dense samples: ~1e-6 m at these distances.
    assert np.abs(p["range"] - expected).max() <= 1e-4
    assert np.abs(xyz - (origin + d * expected[:, None])).max() <= 1e-4


def test_sensor_driving_straight_turns_the_pattern_once(monkeypatch):
    """A sensor that drives without turning (a tilted mount, 10 m/s along x) takes the
    translation-only path (one rotation for the sweep, an origin per firing time): its
    points agree with the per-firing-time rotations of the general path within 1e-9 m
    and with the analytic ranges."""
    room = box_geometry((-10, -6, -1), (10, 6, 5))
    tilt = np.deg2rad(20.0)

    def pose(t):
        m = translation(-2 + 10 * t, 0.5, 1.5)
        m[:3, :3] = [[np.cos(tilt), 0, np.sin(tilt)], [0, 1, 0], [-np.sin(tilt), 0, np.cos(tilt)]]
        return m

    times = np.linspace(0, T, 5)
    track = Track(times, [pose(t) for t in times])
    assert track.linear_is_constant
    pat = pattern()
    fast = scan_frame(room, pat, pose(0), PRESET, EXACT, NumpyCaster, sensor_track=track).points
    monkeypatch.setattr(Track, "linear_is_constant", property(lambda self: False))
    general = scan_frame(room, pat, pose(0), PRESET, EXACT, NumpyCaster,
                         sensor_track=track).points
    assert len(fast) == len(general) == len(pat)
    for f in ("x", "y", "z", "range"):
        assert np.abs(fast[f] - general[f]).max() <= 1e-9, f
    t = fast["time"]
    origin = np.stack([-2 + 10 * t, np.full_like(t, 0.5), np.full_like(t, 1.5)], 1)
    d = pat.directions @ pose(0)[:3, :3].T
    lo, hi = np.array([-10, -6, -1]), np.array([10, 6, 5])
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = np.where(d > 0, (hi - origin) / d, np.where(d < 0, (lo - origin) / d, np.inf))
    assert np.abs(fast["range"] - tt.min(axis=1)).max() <= 1e-6


def test_several_moving_objects_in_one_group_match_separate_casts():
    """Objects share one structure side by side; a ray cast for one must never hit a
    neighbour's slot. A small box ahead and a tall board behind the sensor: rays that
    pass over the box would, laid out naively, run on into the board's slot."""
    from rls_addon.core.world.bodies import RigidBodies
    from rls_addon.core.scene.geometry import ObjectInfo

    shapes = [((-1, -1, -1), (1, 1, 1), (10, 0, 0), V),
              ((-1, -10, -10), (1, 10, 10), (-30, 0, 0), -V),
              ((-2, -1, -1), (2, 1, 1), (0, 12, 0), 0.5 * V)]
    objects = [ObjectInfo(f"object {k}", 11, k + 1) for k in range(len(shapes))]  # one table
    parts, halves = [], []
    for k, (lo, hi, at, vy) in enumerate(shapes):
        one = box_geometry(lo, hi)
        local = SceneGeometry(one.vertices, one.triangles, np.full(12, k), one.tri_material,
                              objects, one.materials)
        start = np.array(at, float)
        parts.append((local, Track([0.0, T], [translation(*start),
                                              translation(*(start + [0, vy * T, 0]))])))
        halves.append(np.array(hi, float))
    pat = spinning_pattern(np.linspace(-15, 15, 16), 10.0, 16 * 3600 * 10)
    static = PreparedScene(empty(), np.zeros(3), 100.0, NumpyCaster)
    grouped = scan_frame(static, pat, np.eye(4), PRESET, EXACT,
                         moving=[RigidBodies(parts, NumpyCaster)]).points
    separate = scan_frame(static, pat, np.eye(4), PRESET, EXACT,
                          moving=[RigidBodies([p], NumpyCaster) for p in parts]).points
    assert len(grouped) > 500 and set(np.unique(grouped["instance"])) == {1, 2, 3}
    assert len(grouped) == len(separate)
    assert np.array_equal(grouped["instance"], separate["instance"])
    assert np.abs(grouped["range"] - separate["range"]).max() <= 1e-9
    for k, (_, track) in enumerate(parts):
        sel = grouped[grouped["instance"] == k + 1]
        centre = track.at(sel["time"])[:, :3, 3]
        xyz = np.stack([sel["x"], sel["y"], sel["z"]], 1)
        assert np.abs(box_sdf(xyz, centre, halves[k])).max() <= 1e-3


@pytest.mark.parametrize("turn_deg", [0.0, 80.0, 350.0])
def test_swept_box_holds_the_object_at_every_time(turn_deg):
    """The world-space cull box of a moving object contains the object at any time of
    the sweep, also along a curved, turning track (a miss here would drop points)."""
    local = box_geometry((-2, -1, -0.7), (2, 1, 0.7), label=11, instance=7)
    times = np.linspace(0.0, T, 5)
    mats = []
    for k, t in enumerate(times):
        ang = np.deg2rad(turn_deg) * t / T
        m = translation(10 * np.sin(ang * 0.5) + 3 * t / T, 5 * t / T, 0.2 * k)
        m[:3, :3] = [[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]
        mats.append(m)
    track = Track(times, mats)
    body = RigidBody(local, track, NumpyCaster)
    lo, hi = body._swept_box(0)
    dense = track.at(np.linspace(0.0, T, 4001))
    w = np.einsum("kij,vj->kvi", dense[:, :3, :3], local.vertices) + dense[:, None, :3, 3]
    assert (w >= lo).all() and (w <= hi).all()
    # ... and it is tight: no wider than the swept vertices plus a few centimetres.
    assert np.all(w.min(axis=(0, 1)) - lo < 0.5) and np.all(hi - w.max(axis=(0, 1)) < 0.5)


def test_accelerating_track_is_exact_at_its_ends():
    """A car braking at 6 m/s^2 along a curve (x = v0 t + a t^2 / 2, y quadratic too),
    sampled at uneven times: finite differences of second order are exact for a
    quadratic at every sample, the first and last included (first order is off by
    a dt / 2 there), so the Hermite interpolation between samples is exact too."""
    v0, acc = np.array([15.0, 2.0, 0.0]), np.array([-6.0, 3.0, 0.0])
    times = np.array([0.0, 0.02, 0.05, 0.07, 0.1])
    track = Track(times, [translation(*(v0 * t + 0.5 * acc * t * t)) for t in times])
    assert np.allclose(track.velocities, v0 + acc * times[:, None], rtol=0, atol=1e-9)
    t = np.array([0.004, 0.011, 0.06, 0.085, 0.097])  # inside the first and last intervals
    exact = v0 * t[:, None] + 0.5 * acc * t[:, None] ** 2
    assert np.allclose(track.positions_at(t), exact, rtol=0, atol=1e-12)
    assert np.allclose(track.at(t)[:, :3, 3], exact, rtol=0, atol=1e-12)
