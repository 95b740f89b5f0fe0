"""A sensor that does not move casts the same rays into the same static scene every
frame: the static cast is kept by the prepared scene and reused, giving what casting
again would give."""

import numpy as np
import pytest

from rls_addon.core.world.bodies import PreparedScene, RigidBodies
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.scene.geometry import MaterialInfo, SceneGeometry
from rls_addon.core.scene.motion import Track
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import DevicePreset, RangeModel
from rls_addon.core.casting import NumpyCaster

from .scenes import box_geometry, merge

PRESET = DevicePreset(id="t", name="t", family="spinning", source="test", frequency_hz=10.0,
                      range=RangeModel(0.1, 60.0, 0.02))
GLASS = MaterialInfo("glass", 0.3, glossy=True, ghost_ratio=0.5)


def factories():
    out = [NumpyCaster]
    from rls_addon.core.casting import embree as embree_caster

    if embree_caster.available():
        out.append(embree_caster.EmbreeCaster)
    return out


def street():
    ground = box_geometry((-40, -40, -2.1), (40, 40, -2.0), label=1, instance=1, name="ground")
    glass = box_geometry((12, -30, -2), (12.2, 30, 6), label=13, instance=2, name="glass",
                         material=GLASS)
    wall = box_geometry((-30, -30, -2), (-29, 30, 6), label=2, instance=3, name="wall")
    return merge(ground, glass, wall)


def pose(x=0.0, yaw_deg=0.0):
    a = np.deg2rad(yaw_deg)
    m = np.eye(4)
    m[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    m[0, 3] = x
    return m


@pytest.fixture
def counted(monkeypatch):
    """Records the scenes whose watertight casts ran (what reuse saves): ``count(scene)``
    gives how many were the given scene's."""
    calls = []
    cast = PreparedScene._start

    def counting(self, origins, directions, max_range, watertight, order):
        if watertight:
            calls.append(self)
        return cast(self, origins, directions, max_range, watertight, order)

    monkeypatch.setattr(PreparedScene, "_start", counting)

    def count(scene):
        return sum(1 for s in calls if s is scene)

    count.reset = calls.clear
    return count


def cold(scene, *args, **kwargs):
    scene.reuse_casts = False
    try:
        return scan_frame(scene, *args, **kwargs)
    finally:
        del scene.reuse_casts


@pytest.mark.parametrize("factory", factories(), ids=lambda f: f.__name__)
def test_frames_of_a_still_sensor_cast_the_static_scene_once(factory, counted):
    scene = PreparedScene(street(), np.zeros(3), 60.0, factory)
    pat = spinning_pattern(np.linspace(-15, 5, 16), 10.0, 16 * 900 * 10)
    frames = [scan_frame(scene, pat, pose(), PRESET, ScanSettings(), frame=f) for f in range(4)]
    assert counted(scene) == 1  # the first frame cast; the others reused it
    assert [f.stats["static_cast_reused"] for f in frames] == [False, True, True, True]
    for f, got in enumerate(frames):
        want = cold(scene, pat, pose(), PRESET, ScanSettings(), frame=f)
        assert got.points.tobytes() == want.points.tobytes()  # noise, ghosts and all
        assert dict(got.stats, static_cast_reused=False) == want.stats
        assert got.warnings == want.warnings
    assert frames[0].stats["ghosts"] > 50  # ghosting changed the frame's own arrays
    assert not np.array_equal(frames[0].points["range"], frames[1].points["range"])  # noise


@pytest.mark.parametrize("factory", factories(), ids=lambda f: f.__name__)
def test_other_rays_are_cast_again(factory, counted):
    scene = PreparedScene(street(), np.zeros(3), 62.0, factory)
    pat = spinning_pattern(np.linspace(-15, 5, 16), 10.0, 16 * 900 * 10)
    exact = ScanSettings(noise=False, dropout=False, ghosting=False, frame_space="world")
    runs = [(pose(), 60.0), (pose(yaw_deg=5.0), 60.0), (pose(x=1.0, yaw_deg=5.0), 60.0),
            (pose(x=1.0, yaw_deg=5.0), 30.0), (pose(x=1.0, yaw_deg=5.0), 30.0)]
    settings = [ScanSettings(**{**exact.__dict__, "max_range_m": rmax}) for _, rmax in runs]
    got = [scan_frame(scene, pat, m, PRESET, s) for (m, _), s in zip(runs, settings)]
    # a new rotation, a new origin (same rotation) and a new range were cast; the last
    # run repeats the one before it
    assert counted(scene) == 4
    for g, (m, _), s in zip(got, runs, settings):
        assert g.points.tobytes() == cold(scene, pat, m, PRESET, s).points.tobytes()
    counted.reset()
    # a new pattern object is new rays, even with the same contents
    same = spinning_pattern(np.linspace(-15, 5, 16), 10.0, 16 * 900 * 10)
    scan_frame(scene, same, runs[-1][0], PRESET, ScanSettings(**{**exact.__dict__,
                                                                 "max_range_m": 30.0}))
    assert counted(scene) == 1


def test_only_read_only_arrays_that_own_their_data_are_kept(counted):
    scene = PreparedScene(street(), np.zeros(3), 60.0, NumpyCaster)
    d = spinning_pattern(np.linspace(-15, 5, 8), 10.0, 8 * 360 * 10).directions.copy()
    o = np.zeros((1, 3))
    first = scene.cast(o, d, 60.0, reuse=True)
    d[:, 2] *= -1  # a writeable array may change between casts: never kept
    flipped = scene.cast(o, d, 60.0, reuse=True)
    assert counted(scene) == 2 and not np.array_equal(first[0], flipped[0])
    view = d[:]
    view.flags.writeable = False  # read-only, but its base may still change
    scene.cast(o, view, 60.0, reuse=True)
    scene.cast(o, view, 60.0, reuse=True)
    assert counted(scene) == 4
    d.flags.writeable = False
    a = scene.cast(o, d, 60.0, reuse=True)
    a[0][:] = -1.0  # the caller's copy: the kept cast is not touched
    b = scene.cast(o, d, 60.0, reuse=True)
    assert counted(scene) == 5 and np.array_equal(b[0], flipped[0])
    # a moving sensor's rays (one origin per ray) are not kept either
    many = np.zeros((len(d), 3))
    scene.cast(many, d, 60.0, reuse=True)
    assert counted(scene) == 6


@pytest.mark.parametrize("factory", factories(), ids=lambda f: f.__name__)
def test_cars_driving_past_a_still_sensor(factory, counted):
    """Only the cars are traced in later frames; every frame equals a cold one."""
    g = street()
    objects = g.objects + [type(g.objects[0])("car", 11, 9)]
    g = SceneGeometry(g.vertices, g.triangles, g.tri_object, g.tri_material, objects,
                      g.materials)
    car = box_geometry((-2, -1, -0.7), (2, 1, 0.7))
    car = SceneGeometry(car.vertices, car.triangles, np.full(12, len(objects) - 1),
                        car.tri_material, objects, g.materials)
    scene = PreparedScene(g, np.zeros(3), 60.0, factory)
    pat = spinning_pattern(np.linspace(-15, 5, 16), 10.0, 16 * 900 * 10)
    exact = ScanSettings(noise=False, dropout=False, frame_space="world")
    frames = []
    for f in range(3):
        x = 6.0 + 3.0 * f
        track = Track([0.0, 0.1], [pose(x) @ _lift(), pose(x + 2.0) @ _lift()])
        rb = RigidBodies([(car, track)], factory)
        frames.append((rb, scan_frame(scene, pat, pose(), PRESET, exact, frame=f, moving=[rb])))
    assert counted(scene) == 1
    for f, (rb, got) in enumerate(frames):
        want = cold(scene, pat, pose(), PRESET, exact, frame=f, moving=[rb])
        assert (got.points["instance"] == 9).sum() > 20
        assert got.points.tobytes() == want.points.tobytes()


def _lift():
    m = np.eye(4)
    m[1, 3], m[2, 3] = 4.0, -1.3
    return m
