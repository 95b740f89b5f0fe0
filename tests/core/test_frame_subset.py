"""``scan_frame(rays=...)`` casts some of a pattern's rays: each returns what it
returns in the whole frame (its draws are the whole frame's), so the points are the
whole frame's points of those rays, byte for byte and in the same order."""

import numpy as np
import pytest

from bench.scene import OPEN_SKY_POSE, open_sky_geometry
from rls_addon.core.world.bodies import PreparedScene
from rls_addon.core.casting import caster_factory
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.scene.motion import Track
from rls_addon.core.device.presets import get_preset
from rls_addon.core.scan.settings import ScanSettings


@pytest.fixture(scope="module")
def sky():
    return open_sky_geometry()


@pytest.mark.parametrize("pid, kw", [
    ("hesai_pandar64", {}),                                   # CARLA's model, ghosts
    ("velodyne_hdl64e", {"footprint": "off", "weather": "fog:visibility=50"}),
    ("livox_avia", {"frame_space": "sensor"}),                # a trace order
    ("hesai_pandar64", {"noise": False, "dropout": False}),
])
def test_a_subset_of_rays_gives_the_whole_frames_points_of_those_rays(sky, pid, kw):
    preset = get_preset(pid)
    pattern = preset.pattern()
    scene = PreparedScene(sky, OPEN_SKY_POSE[:3, 3], preset.range.max_m,
                          caster_factory("auto")[0])
    settings = ScanSettings(seed=4, **{"frame_space": "world", **kw})
    full = scan_frame(scene, pattern, OPEN_SKY_POSE, preset, settings, frame=3,
                      keep_rays=True)
    rng = np.random.default_rng(1)
    for rows in (np.sort(rng.choice(len(pattern), len(pattern) // 3, replace=False)),
                 np.arange(len(pattern) // 2, len(pattern)),      # a contiguous half
                 np.zeros(0, np.int64)):
        sub = scan_frame(scene, pattern, OPEN_SKY_POSE, preset, settings, frame=3,
                         keep_rays=True, rays=rows)
        want = full.points[np.isin(full.rays_cast.point_ray, rows)]
        assert sub.rays == len(rows)
        assert len(sub.points) == len(want) and (len(rows) == 0 or len(want) > 1000)
        assert sub.points.tobytes() == want.tobytes()
        np.testing.assert_array_equal(rows[sub.rays_cast.point_ray],
                                      full.rays_cast.point_ray[np.isin(
                                          full.rays_cast.point_ray, rows)])
    if pid == "hesai_pandar64" and not kw:
        assert full.stats["ghosts"] > 0  # the glossy boxes sent ghosts


def test_a_subset_is_refused_where_rays_depend_on_their_neighbours(sky):
    preset = get_preset("velodyne_hdl64e")  # a beam divergence: footprints by default
    pattern = preset.pattern()
    scene = PreparedScene(sky, OPEN_SKY_POSE[:3, 3], preset.range.max_m + 50,
                          caster_factory("auto")[0])
    with pytest.raises(ValueError, match="footprints"):
        scan_frame(scene, pattern, OPEN_SKY_POSE, preset, ScanSettings(), rays=[0, 1])
    moving = np.repeat(OPEN_SKY_POSE[None], 2, axis=0)
    moving[1, 0, 3] += 1.0
    with pytest.raises(ValueError, match="still sensor"):
        scan_frame(scene, pattern, OPEN_SKY_POSE, preset, ScanSettings(footprint="off"),
                   sensor_track=Track(np.array([0.0, 0.1]), moving), rays=[0, 1])
    with pytest.raises(ValueError, match="indices"):
        scan_frame(scene, pattern, OPEN_SKY_POSE, preset, ScanSettings(footprint="off"),
                   rays=[len(pattern)])
