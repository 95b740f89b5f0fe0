"""The compiled per-hit stage (native/c/points.c) and the compiled watertight re-check
(native/c/embree_loop.c) write the same bytes as their numpy references
(``assemble.assemble_numpy``, ``WatertightCaster._recheck``), and the re-check casts
no more than a leak needs."""

import numpy as np
import pytest

from rls_addon.core.physics import assemble, ghost
from rls_addon.core.world import returns
from rls_addon.core.physics.assemble import Draws, Effects, Hits, Rays, assemble_numpy
from rls_addon.core.world.bodies import PreparedScene
from rls_addon.core.casting import embree
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.points import POINT_DTYPE
from rls_addon.core.device.presets import get_preset
from rls_addon.core.scan.settings import ScanSettings
from tests.core.built import require_built
from tests.core.scenes import open_sky


@pytest.fixture(scope="module")
def native():
    return require_built(assemble.POINTS)[0]


def random_frame(n, seed, ghosts=True, per_ray_origins=False):
    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[rng.random(n) < 0.1] = 0.0  # misses carry zero normals
    valid = rng.random(n) < 0.7
    dist = np.where(valid, rng.uniform(0.1, 120.0, n), np.inf)
    surface = np.stack([rng.integers(0, 7, n), rng.integers(0, 5, n)], 1).astype(np.int32)
    ghost, rows = None, np.zeros(0, np.int64)
    gdot, gint = np.zeros(0), np.zeros(0)
    if ghosts:
        rows = np.sort(rng.choice(np.nonzero(valid)[0], size=max(1, n // 50), replace=False))
        ghost = np.zeros(n, np.uint8)
        ghost[rows] = 1
        gdot = rng.uniform(-1, 1, len(rows))
        gint = rng.uniform(0, 0.8, len(rows))
    hits = Hits(dist, valid, surface, normals, ghost, rows, gdot, gint,
                rng.uniform(0.05, 1.2, 5), rng.integers(0, 20, 7).astype(np.uint32),
                rng.integers(0, 2**31, 7).astype(np.uint32))
    origins = rng.normal(size=(n, 3)) * 50 if per_ray_origins else rng.normal(size=(1, 3)) * 1e4
    cols = tuple(np.ascontiguousarray(c) for c in rng.normal(size=(3, n)))
    rays = Rays(dirs, origins, cols, rng.integers(0, 128, n).astype(np.uint16),
                np.sort(rng.uniform(0, 0.1, n)))
    draws = Draws(noise=(rng.normal(size=n) * 0.5).astype(np.float32),
                  general=rng.random(n), low=rng.random(n))
    return hits, rays, draws


EFFECTS = Effects(general_rate=0.05, intensity_limit=0.3, intensity_zero=0.4)


@pytest.mark.parametrize("space", ["sensor", "world"])
@pytest.mark.parametrize("fields", [None, ("x", "y", "label"), ("intensity", "ghost", "time")])
@pytest.mark.parametrize("case", ["plain", "per_ray_origins", "no_ghosts", "no_draws"])
def test_compiled_assembly_writes_the_reference_bytes(native, space, fields, case):
    hits, rays, draws = random_frame(50_000, 3, ghosts=case != "no_ghosts",
                                     per_ray_origins=case == "per_ray_origins")
    effects = EFFECTS
    if case == "no_draws":
        draws, effects = Draws(), Effects()
    want = assemble_numpy(hits, rays, draws, effects, space, fields)
    got = assemble._assemble_native(native, hits, rays, draws, effects, space, fields)
    assert got[0].dtype == want[0].dtype
    assert len(want[0]) > 1000  # noise, dropout and misses leave a real cloud
    assert got[0].tobytes() == want[0].tobytes()
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[2], want[2])


def test_compiled_assembly_edge_cases(native):
    for n in (0, 1, 17, 40_000):
        hits, rays, draws = random_frame(n, 5, ghosts=n > 100)
        want = assemble_numpy(hits, rays, draws, EFFECTS, "world")
        got = assemble._assemble_native(native, hits, rays, draws, EFFECTS, "world", None)
        assert got[0].tobytes() == want[0].tobytes() and len(got[1]) == len(want[1])
    hits, rays, draws = random_frame(1000, 6, ghosts=False)
    hits.valid[:] = False  # nothing returned
    got = assemble._assemble_native(native, hits, rays, draws, EFFECTS, "sensor", None)
    assert len(got[0]) == 0 and got[0].dtype == POINT_DTYPE


@pytest.mark.parametrize("threads", [1, 3, 5])
def test_compiled_assembly_joins_its_shares_in_ray_order(native, monkeypatch, threads):
    # each thread writes its share's points from the share's first ray on; the shares
    # are then moved down to follow each other (some shares with no point at all)
    monkeypatch.setattr(assemble.kernels, "threads", lambda: threads)
    hits, rays, draws = random_frame(90_000, 11)
    hits.valid[20_000:40_000] = False
    want = assemble_numpy(hits, rays, draws, EFFECTS, "sensor")
    got = assemble._assemble_native(native, hits, rays, draws, EFFECTS, "sensor", None)
    assert got[0].tobytes() == want[0].tobytes()
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[2], want[2])


def _with_effects(hits, n, rng, medium, echoes):
    """``hits`` with false returns from the air on some rays and footprint echoes (with
    return numbers) on others, as frame.py hands them over."""
    import dataclasses

    changes = {}
    if medium:
        rows = np.sort(rng.choice(n, n // 20, replace=False))
        changes.update(medium_rows=rows, medium_dist=rng.uniform(2.0, 40.0, len(rows)))
    if echoes:
        rows = np.sort(rng.choice(n, n // 30, replace=False))
        changes.update(echo_rows=rows, echo_rho_cos=rng.uniform(0, 1, len(rows)),
                       echo_carla=rng.uniform(0, 1, len(rows)),
                       return_index=rng.integers(1, 3, n).astype(np.uint8),
                       num_returns=rng.integers(1, 3, n).astype(np.uint8))
    return dataclasses.replace(hits, **changes)


@pytest.mark.parametrize("space", ["sensor", "world"])
@pytest.mark.parametrize("case", ["equation", "strength", "carla_weather", "fog_echoes",
                                  "attenuation", "attenuation_echoes"])
@pytest.mark.parametrize("fields", [None, ("x", "label", "instance", "ghost", "num_returns")])
def test_compiled_records_of_the_lidar_equation_write_the_reference_bytes(native, space,
                                                                          case, fields):
    # intensity and detection in numpy (exp, log, tanh), noise, dropout and records in C
    from rls_addon.core.physics.detection import detection_of

    n = 60_000
    hits, rays, draws = random_frame(n, 21, per_ray_origins=space == "world")
    rng = np.random.default_rng(22)
    model = detection_of(get_preset("livox_mid40"), ScanSettings())
    alpha = 0.06 if case in ("carla_weather", "fog_echoes") else 0.0
    effects = {
        "equation": Effects(0.05, 0.3, 0.4, 0.0, model, "reflectivity"),
        "strength": Effects(0.0, 0.0, 0.0, 0.0, model, "strength"),
        "carla_weather": Effects(0.05, 0.3, 0.4, 0.0, None, "carla", alpha),
        "fog_echoes": Effects(0.0, 0.0, 0.0, 0.0, model, "reflectivity", alpha),
        "attenuation": Effects(0.05, 0.3, 0.4, 0.004),
        "attenuation_echoes": Effects(0.0, 0.0, 0.0, 0.004),
    }[case]
    hits = _with_effects(hits, n, rng, medium=alpha > 0, echoes="echoes" in case)
    hits.dist[hits.valid] *= 3.0  # ranges out to the model's limits
    draws.detect = rng.random(n)
    if not effects.general_rate:  # as effects.dropout_draws: drawn only when used
        draws.general = draws.low = None
    want = assemble_numpy(hits, rays, draws, effects, space, fields)
    got = assemble._assemble(native, hits, rays, draws, effects, space, fields)
    assert len(want[0]) > 1000
    if effects.general_rate or effects.detection is not None:  # something was dropped
        assert len(want[0]) < 0.95 * np.count_nonzero(hits.valid)
    assert got[0].dtype == want[0].dtype
    assert got[0].tobytes() == want[0].tobytes()
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[2], want[2])
    if alpha and (fields is None or "label" in fields):
        assert (got[0]["label"] == assemble.WEATHER_LABEL).any()


def test_the_reference_is_what_the_frame_used_to_compute():
    """The reference's intensity and dropout, checked against their definitions."""
    hits, rays, draws = random_frame(5000, 8, ghosts=False)
    pts, idx, back = assemble_numpy(hits, rays, draws, EFFECTS, "sensor")
    cos = np.abs(np.einsum("ij,ij->i", hits.normals, rays.dirs))[idx]
    inten = np.clip(hits.reflectivity[hits.surface[idx, 1]] * cos, 0, 1)
    np.testing.assert_allclose(pts["intensity"], inten.astype(np.float32), rtol=1e-6)
    assert np.all(draws.general[idx] >= EFFECTS.general_rate)
    low = inten <= EFFECTS.intensity_limit
    p = EFFECTS.intensity_zero / EFFECTS.intensity_limit * inten + 1 - EFFECTS.intensity_zero
    assert np.all(draws.low[idx][low] < p[low])
    np.testing.assert_allclose(pts["range"], hits.dist[idx] + draws.noise[idx])
    assert np.all(pts["range"] > 0) and np.all(hits.valid[idx])
    assert np.array_equal(back, np.einsum("ij,ij->i", hits.normals, rays.dirs)[idx] > 0)


def _modes(scene, on):
    scene.caster.compiled = on
    assemble.compiled = ghost.compiled = returns.compiled = on


@pytest.mark.parametrize("space", ["sensor", "world"])
def test_frames_are_byte_identical_compiled_or_numpy(space):
    if not embree.available() or embree._native_loop() is None:
        pytest.fail("embreex and the compiled loop are needed (make test installs and builds them)")
    preset = get_preset("hesai_pandar64")
    pose = np.eye(4)
    pose[:3, 3] = (0.3, -0.2, 4.0)
    scene = PreparedScene(open_sky(), pose[:3, 3], preset.range.max_m, embree.EmbreeCaster)
    scene.reuse_casts = False
    settings = ScanSettings(frame_space=space)
    try:
        clouds = []
        for on in (True, False):
            _modes(scene, on)
            scene.caster.retried = 0
            res = scan_frame(scene, preset.pattern(), pose, preset, settings, frame=4)
            clouds.append((res.points.tobytes(), scene.caster.retried, res.stats["ghosts"]))
    finally:
        _modes(scene, True)
    assert clouds[0] == clouds[1]
    assert clouds[0][2] > 0  # the glossy box made ghosts: their rows went through too
    assert len(clouds[0][0]) > 10_000 * POINT_DTYPE.itemsize


def test_a_driving_sensor_frame_is_byte_identical_compiled_or_numpy():
    """Per-ray origins (a sensor driving at 10 m/s): the prefilter takes the origins'
    bounds, in C and in numpy alike."""
    from rls_addon.core.scene.motion import Track

    preset = get_preset("hesai_pandar64")
    start, end = np.eye(4), np.eye(4)
    start[:3, 3], end[:3, 3] = (-5.0, 0.5, 4.0), (-4.0, 0.5, 4.0)
    track = Track(np.array([0.0, 0.1]), np.stack([start, end]))
    scene = PreparedScene(open_sky(), start[:3, 3], preset.range.max_m + 2.0,
                          embree.EmbreeCaster)
    scene.reuse_casts = False
    got = []
    try:
        for on in (True, False):
            _modes(scene, on)
            scene.caster.retried = 0
            res = scan_frame(scene, preset.pattern(), start, preset, ScanSettings(),
                             frame=2, sensor_track=track)
            got.append((res.points.tobytes(), scene.caster.retried))
    finally:
        _modes(scene, True)
    assert got[0] == got[1] and len(got[0][0]) > 10_000 * POINT_DTYPE.itemsize
