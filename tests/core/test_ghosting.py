"""Ghost points from glossy surfaces against the mirror image (exact numpy caster)."""

import numpy as np

from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scan.settings import ScanSettings
from rls_addon.core.scene.geometry import MaterialInfo
from rls_addon.core.device.patterns.spinning import spinning_pattern
from rls_addon.core.device.presets import DevicePreset, RangeModel
from rls_addon.core.casting import NumpyCaster

from .scenes import box_geometry, box_sdf, merge

PRESET = DevicePreset(id="t", name="t", family="spinning", source="test", frequency_hz=10.0,
                      range=RangeModel(0.1, 100.0, 0.02))
CLEAN = dict(noise=False, dropout=False, frame_space="world")
MIRROR = MaterialInfo("mirror", 0.9, glossy=True, ghost_ratio=0.5)


def mirror_scene(mirror_material=MIRROR):
    """A glass wall at x = 5 (glossy) and a 1 x 2 x 2 m box behind the sensor at x = -3..-2."""
    wall = box_geometry((5.0, -20, -5), (5.2, 20, 5), label=13, instance=1, name="glass",
                        material=mirror_material)
    box = box_geometry((-3.0, -1, -1), (-2.0, 1, 1), label=11, instance=2, name="car")
    return merge(wall, box)


def pattern(channels=16, steps=3600):
    return spinning_pattern(np.linspace(-10, 10, channels), 10.0, channels * steps * 10)


def test_ghost_points_coincide_with_the_mirror_image_of_the_box():
    res = scan_frame(mirror_scene(), pattern(), np.eye(4), PRESET, ScanSettings(**CLEAN),
                     NumpyCaster)
    p = res.points
    g = p[p["ghost"] == 1]
    assert len(g) > 100
    assert set(np.unique(g["label"])) == {11} and set(np.unique(g["instance"])) == {2}
    xyz = np.stack([g["x"], g["y"], g["z"]], 1)
    assert xyz[:, 0].min() > 5.0  # ghosts appear behind the mirror ...
    image = xyz.copy()
    image[:, 0] = 2 * 5.0 - image[:, 0]  # ... and their mirror image lies on the box
    err = np.abs(box_sdf(image, np.array([-2.5, 0, 0]), np.array([0.5, 1, 1])))
    assert err.max() <= 1e-4
    assert np.allclose(g["range"], np.linalg.norm(xyz, axis=1), atol=1e-9)


def test_ghost_ratio_over_many_glossy_hits():
    """A closed room whose +X wall is a mirror: every reflected beam finds a wall."""
    room_mirror = box_geometry((9.8, -10, -10), (10, 10, 10), label=13, material=MIRROR)
    room = box_geometry((-10, -10, -10), (10.5, 10, 10), label=4, instance=2, name="room")
    pat = pattern(channels=64, steps=7000)
    res = scan_frame(merge(room_mirror, room), pat, np.eye(4), PRESET,
                     ScanSettings(**CLEAN), NumpyCaster)
    glossy = res.stats["glossy_hits"]
    assert glossy >= 100_000
    assert res.stats["bounce_rays"] == res.stats["ghosts"]  # all reflections came back
    ratio = res.stats["ghosts"] / glossy
    assert abs(ratio - 0.5) <= 0.01
    assert (res.points["ghost"] == 1).sum() == res.stats["ghosts"]


def test_ghosting_off_gives_exactly_the_baseline_cloud():
    def scene(material):
        wall = box_geometry((5.0, -20, -5), (5.2, 20, 5), label=4, instance=1, material=material)
        return merge(wall, box_geometry((-3.0, -1, -1), (-2.0, 1, 1), label=11, instance=2))

    matte = MaterialInfo("matte", 0.9)
    base = scan_frame(scene(matte), pattern(), np.eye(4), PRESET, ScanSettings(seed=5),
                      NumpyCaster).points
    off = scan_frame(scene(MIRROR), pattern(), np.eye(4), PRESET,
                     ScanSettings(seed=5, ghosting=False), NumpyCaster).points
    assert base.tobytes() == off.tobytes()
    # No glossy surface: ghosting on costs nothing and changes nothing.
    on = scan_frame(scene(matte), pattern(), np.eye(4), PRESET,
                    ScanSettings(seed=5, ghosting=True), NumpyCaster)
    assert on.points.tobytes() == base.tobytes() and on.stats["bounce_rays"] == 0
    # With ghosts, every ray that did not hit the mirror keeps its exact point
    # (noise and dropout are drawn per ray).
    ghosted = scan_frame(scene(MIRROR), pattern(), np.eye(4), PRESET, ScanSettings(seed=5),
                         NumpyCaster).points
    keep_b = base[base["instance"] != 1]
    keep_g = ghosted[(ghosted["instance"] != 1) & (ghosted["ghost"] == 0)]
    assert keep_b.tobytes() == keep_g.tobytes()


def test_reflected_beam_that_finds_nothing_returns_nothing():
    wall = box_geometry((5.0, -20, -5), (5.2, 20, 5), label=13, material=MIRROR)
    res = scan_frame(wall, pattern(), np.eye(4), PRESET, ScanSettings(**CLEAN), NumpyCaster)
    glossy, ghosts = res.stats["glossy_hits"], res.stats["ghosts"]
    assert ghosts == 0 and glossy > 0
    # Roughly half of the glossy hits vanished (their reflection escaped to the sky).
    assert abs(len(res.points) - glossy / 2) < 0.05 * glossy
    assert (res.points["ghost"] == 0).all()


def test_glossy_by_label_smoothness():
    """Surfaces labelled glass are glossy even with a plain material."""
    wall = box_geometry((5.0, -20, -5), (5.2, 20, 5), label=13, material=MaterialInfo("m", 0.5))
    box = box_geometry((-3.0, -1, -1), (-2.0, 1, 1), label=11, instance=2)
    res = scan_frame(merge(wall, box), pattern(), np.eye(4), PRESET, ScanSettings(**CLEAN),
                     NumpyCaster)
    assert res.stats["ghosts"] > 0
