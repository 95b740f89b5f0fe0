"""Moving objects traced as Embree instances in one traversal with the static scene
(``core/world/instancing.py``): same points as the portable per-object path, exact against
analytic motion, and the caches that carry a body from frame to frame."""

import numpy as np
import pytest

from rls_addon.core.world import instancing
from rls_addon.core.world.bodies import PreparedScene, RigidBodies
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.world.world import World
from rls_addon.core.scene.geometry import ObjectInfo, SceneGeometry
from rls_addon.core.scene.motion import Track
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import DevicePreset, RangeModel
from rls_addon.core.casting import NumpyCaster, WatertightCaster

from rls_addon.core.casting import embree as embree_caster

from .external_tools import require_backend
from .scenes import box_geometry, box_sdf, merge


@pytest.fixture(autouse=True, scope="module")
def _embreex():
    require_backend(embree_caster, "embreex")


Embree = embree_caster.EmbreeCaster


@pytest.fixture(autouse=True, params=["one traversal", "static cast kept"])
def static_cast(request, monkeypatch):
    """Every test both ways: the static scene and the cars in one traversal (a frame
    whose static cast cannot be reused), and the static cast kept by the scene with
    only the cars traced (a sensor that does not move, see PreparedScene.cast)."""
    monkeypatch.setattr(PreparedScene, "reuse_casts", request.param == "static cast kept")
    return request.param

PRESET = DevicePreset(id="t", name="t", family="spinning", source="test", frequency_hz=10.0,
                      range=RangeModel(0.1, 100.0, 0.0))
EXACT = ScanSettings(noise=False, dropout=False, frame_space="world", ghosting=False)
T = 0.1


def pose(x, y, z, yaw_deg=0.0):
    m = np.eye(4)
    a = np.deg2rad(yaw_deg)
    m[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    m[:3, 3] = (x, y, z)
    return m


def pattern():
    return spinning_pattern(np.linspace(-12, 6, 16), 10.0, 16 * 1800 * 10)


def street():
    """Ground at z = -1.5 and a wall at x = 30 (static), one table for every body."""
    ground = box_geometry((-40, -40, -1.6), (40, 40, -1.5), label=1, instance=1, name="ground")
    wall = box_geometry((30, -40, -1.5), (31, 40, 8), label=2, instance=2, name="wall")
    return merge(ground, wall)


def car(k, objects, lo=(-2, -1, -0.7), hi=(2, 1, 0.7)):
    one = box_geometry(lo, hi)
    return SceneGeometry(one.vertices, one.triangles, np.full(12, k), one.tri_material,
                         objects, one.materials)


def turning_track(start, turn_deg, samples=5):
    times = np.linspace(0.0, T, samples)
    mats = []
    for t in times:
        f = t / T
        m = pose(start[0] + 8 * np.sin(np.deg2rad(turn_deg) * f * 0.5), start[1] + 12 * f,
                 start[2], turn_deg * f)
        mats.append(m)
    return Track(times, mats)


def bodies(static_geometry, factory):
    """Three cars: straight at 20 m/s, turning 80 deg on a curve, and one parked."""
    objects = static_geometry.objects + [ObjectInfo(f"car {k}", 11, 10 + k) for k in range(3)]
    g = SceneGeometry(static_geometry.vertices, static_geometry.triangles,
                      static_geometry.tri_object, static_geometry.tri_material, objects,
                      static_geometry.materials)
    base = len(static_geometry.objects)
    parts = [(car(base, objects), Track([0.0, T], [pose(10, -6, -0.8), pose(10, -4, -0.8)])),
             (car(base + 1, objects), turning_track((-12, -8, -0.8), 80.0)),
             (car(base + 2, objects), Track.fixed(pose(0, 9, -0.8, 30)))]
    return g, RigidBodies(parts, factory)


def scan(factory, portable=False, monkeypatch=None, **settings):
    g, rb = bodies(street(), factory)
    static = PreparedScene(g, np.zeros(3), 100.0, factory)
    if portable:
        monkeypatch.setattr(instancing.InstancedWorld, "build",
                            classmethod(lambda cls, s, m, with_static=True: None))
    s = ScanSettings(**{**EXACT.__dict__, **settings})
    return scan_frame(static, pattern(), pose(0, 0, 0), PRESET, s, moving=[rb]), rb


def keyed(points):
    return {(int(r), float(t)): k for k, (r, t) in enumerate(zip(points["ring"], points["time"]))}


def test_embree_worlds_with_rigid_bodies_are_instanced():
    g, rb = bodies(street(), Embree)
    world = World(PreparedScene(g, np.zeros(3), 100.0, Embree), [rb])
    assert world.instanced is not None
    # one instance for the static scene, one per car but the one turning too fast for
    # Embree's steps (cast the portable way)
    assert len(world.instanced.parts) == 2 and world.instanced.first == 1
    assert world.instanced.portable == {1: [1]}
    # other backends cast each body on its own
    g, rb = bodies(street(), NumpyCaster)
    assert World(PreparedScene(g, np.zeros(3), 100.0, NumpyCaster), [rb]).instanced is None
    # without the static scene: one instance per car (but that one)
    g, rb = bodies(street(), Embree)
    alone = instancing.InstancedWorld.build(PreparedScene(g, np.zeros(3), 100.0, Embree), [rb],
                                            with_static=False)
    assert len(alone.parts) == 2 and alone.first == 0 and alone.portable == {1: [1]}


def test_instanced_scan_equals_the_portable_path(monkeypatch):
    inst, rb = scan(Embree)
    port, _ = scan(Embree, portable=True, monkeypatch=monkeypatch)
    a, b = inst.points, port.points
    assert set(np.unique(a["instance"])) >= {1, 2, 10, 11, 12}
    ka, kb = keyed(a), keyed(b)
    # the same rays return (a ray grazing a silhouette may differ by float32 rounding)
    assert len(set(ka) ^ set(kb)) <= 2
    common = sorted(set(ka) & set(kb))
    ia, ib = [ka[k] for k in common], [kb[k] for k in common]
    assert np.array_equal(a["instance"][ia], b["instance"][ib])
    assert np.abs(a["range"][ia] - b["range"][ib]).max() <= 1e-5


def test_instanced_points_lie_on_each_car_at_its_own_time():
    res, rb = scan(Embree)
    p = res.points
    for k, track in enumerate(rb.tracks):
        sel = p[p["instance"] == 10 + k]
        assert len(sel) > 50
        m = track.at(sel["time"])
        xyz = np.stack([sel["x"], sel["y"], sel["z"]], 1) - m[:, :3, 3]
        local = np.einsum("nji,nj->ni", m[:, :3, :3], xyz)  # rotation^T (world - origin)
        err = np.abs(box_sdf(local, np.zeros(3), np.array([2, 1, 0.7])))
        assert err.max() <= 1e-5, (k, err.max())
    ground = p[p["instance"] == 1]
    assert np.abs(ground["z"] + 1.5).max() <= 1e-9


def realistic_turn():
    """A car at 15 m/s turning at 40 deg/s, sampled at 5 poses over the sweep."""
    times = np.linspace(0.0, T, 5)
    mats = []
    for t in times:
        yaw = 40.0 * t
        r = 15.0 / np.deg2rad(40.0)
        a = np.deg2rad(yaw)
        mats.append(pose(5 + r * np.sin(a), -6 + r * (1 - np.cos(a)), -0.8, yaw))
    return Track(times, mats)


def test_steps_follow_the_track_within_the_tolerance():
    g, rb = bodies(street(), Embree)
    world = World(PreparedScene(g, np.zeros(3), 100.0, Embree), [rb])
    iw = world.instanced
    got = [iw._steps(tr, rb.centres[k], rb.local[k][0]) for k, tr in enumerate(rb.tracks)]
    # straight at constant speed: two steps are exact; parked: one
    assert len(got[0][0]) == 2 and got[0][1] and len(got[2][0]) == 1 and got[2][1]
    # 120 m/s through an 80 deg turn in 0.1 s: beyond Embree's 129 steps, so that car
    # is cast the portable way instead (exact at each ray's time, see above)
    assert len(got[1][0]) == instancing.MAX_STEPS and not got[1][1]
    assert iw.portable == {1: [1]}
    tr = realistic_turn()
    s, close = iw._steps(tr, rb.centres[1], rb.local[1][0])
    assert close and 2 < len(s) < instancing.MAX_STEPS
    t = np.random.default_rng(1).uniform(0, T, 2000)
    f = t / T * (len(s) - 1)
    i = np.minimum(f.astype(int), len(s) - 2)
    a = (f - i)[:, None, None]
    lerp = (1 - a) * s[i] + a * s[i + 1]
    shift = np.eye(4)
    shift[:3, 3] = rb.centres[1]
    exact = tr.at(t) @ shift
    corners = np.array([[x, y, z, 1] for x in (-2, 2) for y in (-1, 1) for z in (-.7, .7)])
    dev = np.einsum("nij,cj->nci", (lerp - exact)[:, :3, :], corners)
    assert np.linalg.norm(dev, axis=2).max() <= 2 * instancing.STEP_TOLERANCE_M


def test_realistic_turn_refined_in_the_loop_matches_the_portable_path(monkeypatch):
    g, rb = bodies(street(), Embree)
    rb.tracks = [rb.tracks[0], realistic_turn(), rb.tracks[2]]
    static = PreparedScene(g, np.zeros(3), 100.0, Embree)
    world = World(static, [rb])
    assert world.instanced.portable == {}
    a = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    monkeypatch.setattr(instancing.InstancedWorld, "build", classmethod(lambda cls, s, m, with_static=True: None))
    b = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    ka, kb = keyed(a), keyed(b)
    assert len(set(ka) ^ set(kb)) <= 2
    common = sorted(set(ka) & set(kb))
    ia, ib = [ka[k] for k in common], [kb[k] for k in common]
    assert (a["instance"][ia] == 11).sum() > 50
    assert np.array_equal(a["instance"][ia], b["instance"][ib])
    # within the step tolerance (and float32 rounding of the ray's time)
    assert np.abs(a["range"][ia] - b["range"][ib]).max() <= 2 * instancing.STEP_TOLERANCE_M


def test_started_casts_equal_blocking_casts():
    """Ghost bounces start their cast and collect it later."""
    g, rb = bodies(street(), Embree)
    world = World(PreparedScene(g, np.zeros(3), 100.0, Embree), [rb])
    pat = pattern()
    o = np.zeros((1, 3))
    got = world.start(o, pat.directions, pat.times, 100.0, watertight=False)()
    want = world.cast(o, pat.directions, pat.times, 100.0, watertight=False)
    for x, y in zip(got, want):
        assert np.array_equal(x, y)
    assert (got[1] == 1).sum() > 100  # rays on the cars, in world body 1


def test_only_moving_objects_no_static_triangles(monkeypatch):
    empty = SceneGeometry(np.zeros((0, 3)), np.zeros((0, 3), int), [], [])
    g, rb = bodies(empty, Embree)
    static = PreparedScene(g, np.zeros(3), 100.0, Embree)
    world = World(static, [rb])
    assert world.instanced is not None and world.instanced.first == 0
    a = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    monkeypatch.setattr(instancing.InstancedWorld, "build", classmethod(lambda cls, s, m, with_static=True: None))
    b = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    assert len(a) > 100 and abs(len(a) - len(b)) <= 2
    assert set(np.unique(a["instance"])) == set(np.unique(b["instance"]))


@pytest.mark.parametrize("factory", [NumpyCaster, Embree], ids=["numpy", "embree"])
def test_a_reused_body_follows_its_new_tracks(factory):
    """The Blender layer keeps a body over frames and gives it each sweep's tracks:
    nothing derived from the old tracks (cull boxes, instance steps) may survive."""
    g, rb = bodies(street(), factory)
    static = PreparedScene(g, np.zeros(3), 100.0, factory)
    scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb])
    moved = [Track(tr.times, tr.matrices + np.array([[0, 0, 0, 0], [0, 0, 0, 9.0],
                                                     [0, 0, 0, 0], [0, 0, 0, 0]]))
             for tr in rb.tracks]
    rb.tracks = moved
    again = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    _, fresh = bodies(street(), factory)
    fresh.tracks = moved
    want = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[fresh]).points
    assert len(again) == len(want)
    assert np.array_equal(again["instance"], want["instance"])
    assert np.abs(again["range"] - want["range"]).max() <= 1e-9


def test_recheck_skips_rays_whose_crack_would_lie_beyond_their_limit():
    """Rays that hit a moving object are re-checked for static cracks only up to that
    hit; from outside every hull box that is where the ray first enters one."""
    wall = box_geometry((5, -3, -3), (6, 3, 3))
    # one hull box around the whole wall block
    wc = WatertightCaster(NumpyCaster, wall.vertices, wall.triangles, cell=100.0)
    d = np.array([[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    o = np.array([[0.0, 0.5, 0.2]])
    dist = np.full(3, np.inf)
    tri = np.full(3, -1)  # pretend all three slipped through
    limit = np.array([np.inf, 8.0, 2.0])  # the last one hit something at 2 m
    won = wc._recheck(o, d, 50.0, dist, tri, limit)
    assert sorted(won) == [0, 1]
    assert np.allclose(dist[:2], 5.0) and tri[2] == -1
    # from inside a hull box every ray is re-checked, whatever its limit (its first
    # hull hit is where it leaves the box, 0.5 m on, beyond the last limit of 0.2 m)
    inside = np.array([[5.5, 0.5, 0.2]])
    dist, tri = np.full(3, np.inf), np.full(3, -1)
    assert wc._starts_inside(inside) and not wc._starts_inside(o)
    limit[2] = 0.2
    assert sorted(wc._recheck(inside, d, 50.0, dist, tri, limit)) == [0, 1, 2]


def jumping_track(samples=65):
    """A car driving along +y whose keyframes put it 3 m aside halfway through the
    sweep, sampled densely (as a sweep whose path bends between frames is): more
    samples than Embree's 129 steps can follow."""
    times = np.linspace(0.0, T, samples)
    return Track(times, [pose(-10 - 3.0 * (t >= T / 2), -6 + 20 * t, -0.8, 30.0 * (t >= T / 2))
                         for t in times])


def test_a_body_whose_track_needs_more_than_embrees_steps_scans_as_the_portable_path(
        monkeypatch):
    g, rb = bodies(street(), Embree)
    rb.tracks = [rb.tracks[0], jumping_track(), rb.tracks[2]]
    static = PreparedScene(g, np.zeros(3), 100.0, Embree)
    iw = World(static, [rb]).instanced
    # the jumping car is cast the portable way; the others stay instances
    assert iw.portable == {1: [1]} and len(iw.parts) == 2
    assert all(len(m) <= instancing.MAX_STEPS for m, _ in rb.derived.values())
    a = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    monkeypatch.setattr(instancing.InstancedWorld, "build",
                        classmethod(lambda cls, s, m, with_static=True: None))
    b = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, moving=[rb]).points
    ka, kb = keyed(a), keyed(b)
    assert len(set(ka) ^ set(kb)) <= 2
    common = sorted(set(ka) & set(kb))
    ia, ib = [ka[k] for k in common], [kb[k] for k in common]
    assert np.array_equal(a["instance"][ia], b["instance"][ib])
    assert np.abs(a["range"][ia] - b["range"][ib]).max() <= 1e-5
    jumped = a["instance"][ia] == 11
    assert jumped.sum() > 50
    assert np.array_equal(a["range"][ia][jumped], b["range"][ib][jumped])
    assert np.array_equal(a["x"][ia][jumped], b["x"][ib][jumped])


def test_every_objects_steps_at_once_equal_each_objects_own():
    """The steps of a sweep's objects worked out together (their tracks evaluated in
    one go, round by round) are each object's own, byte for byte: driving, turning,
    accelerating, jumping (beyond Embree's steps), two-knot and parked tracks."""
    g, rb = bodies(street(), Embree)
    iw = World(PreparedScene(g, np.zeros(3), 100.0, Embree), [rb]).instanced
    times = np.linspace(0.0, T, 9)
    braking = Track(times, [pose(4 + 12 * t - 30 * t * t, 3, -0.8, 50 * t * t) for t in times])
    tracks = [*rb.tracks, realistic_turn(), jumping_track(), braking]
    objects = [(tr, rb.centres[k % 3], rb.local[k % 3][0]) for k, tr in enumerate(tracks)]
    together = iw._steps_many(objects)
    for obj, (m, close) in zip(objects, together):
        ref, ref_close = iw._steps(*obj)
        assert close == ref_close and np.array_equal(m, ref)
    assert [len(m) for m, _ in together][:3] == [2, instancing.MAX_STEPS, 1]



def test_the_steps_check_a_box_at_its_eight_corners_in_meshgrids_order():
    """The corners the steps are checked at (picked from a body's least and greatest
    coordinates, ``_CORNER_BITS``) are the box's eight corners as np.meshgrid lays
    them out, bit for bit."""
    rng = np.random.default_rng(4)
    v = rng.normal(size=(50, 3)) * [4.0, 1.0, 0.7]
    lo, hi = v.min(0), v.max(0)
    grid = np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), -1).reshape(-1, 3)
    assert np.array_equal(np.where(instancing._CORNER_BITS, hi, lo), grid)


def test_a_driving_sensors_static_scene_is_traced_with_its_instances(static_cast):
    """A driving sensor's ray origins are new every frame (read-only, with their bounds
    kept: track_set.positions_at), so its static scene is never cast apart to be kept
    (PreparedScene.cast's reuse is for a sensor that does not move): one traversal of
    the static scene and the cars, one instanced world built."""
    g, rb = bodies(street(), Embree)
    static = PreparedScene(g, np.zeros(3), 110.0, Embree)
    drive = Track([0.0, T], [pose(0, 0, 0), pose(1, 0, 0)])
    res = scan_frame(static, pattern(), pose(0, 0, 0), PRESET, EXACT, sensor_track=drive,
                     moving=[rb])
    assert len(res.points) > 1000 and not res.stats["static_cast_reused"]
    assert list(static.instanced_cache) == [True]
