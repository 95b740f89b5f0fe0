"""Track.rotate: each vector turned by the track's rotation at its own time, without a
matrix per time, equals the matrices' (polar-decomposed) rotations to rounding."""

import numpy as np
import pytest

from rls_addon.core.scan.frame import sensor_axes
from rls_addon.core.scene.motion import Track


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


@pytest.mark.parametrize("seed", range(20))
def test_rotate_is_the_rotation_at_each_time(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 12))
    t = np.sort(rng.uniform(0, 0.1, n))
    t[0] = 0.0
    m = np.repeat(np.eye(4)[None], n, 0)
    for k in range(n):  # turns of up to 170 deg between knots, any axis
        m[k, :3, :3] = rotation(rng.normal(size=3), rng.uniform(-3, 3))
        m[k, :3, 3] = rng.normal(size=3)
    track = Track(t, m)
    assert track.is_rigid
    times = rng.uniform(-0.01, 0.11, 4000)  # clamped outside the knots, as ``at``
    v = rng.normal(size=(4000, 3))
    want = np.einsum("nij,nj->ni", sensor_axes(track.at(times))[1], v)
    np.testing.assert_allclose(track.rotate(times, v), want, rtol=0, atol=1e-13)


def test_a_scaled_or_mirrored_track_is_not_rigid():
    m = np.repeat(np.eye(4)[None], 2, 0)
    m[1, :3, :3] = rotation([0, 0, 1], 0.5)
    assert Track(np.array([0.0, 0.1]), m).is_rigid
    scaled = m.copy()
    scaled[:, 0, 0] *= 2.0
    assert not Track(np.array([0.0, 0.1]), scaled).is_rigid
    mirrored = m.copy()
    mirrored[:, :3, 1] *= -1.0
    assert not Track(np.array([0.0, 0.1]), mirrored).is_rigid


def test_blenders_float32_matrices_take_the_fast_way_and_agree():
    """Blender's world matrices are float32: their scale is 1 to about 1e-7."""
    t = np.linspace(0.0, 0.1, 9)
    m = np.repeat(np.eye(4)[None], 9, 0)
    for k, yaw in enumerate(np.linspace(0.0, 0.3, 9)):
        m[k, :3, :3] = rotation([0.1, 0.2, 1.0], yaw)
    m = m.astype(np.float32).astype(np.float64)
    track = Track(t, m)
    assert track.is_rigid
    times = np.linspace(0.0, 0.1, 3000)
    v = np.random.default_rng(0).normal(size=(3000, 3))
    want = np.einsum("nij,nj->ni", sensor_axes(track.at(times))[1], v)
    np.testing.assert_allclose(track.rotate(times, v), want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_positions_by_interval_are_the_positions_gathered_per_time(seed):
    """Track._hermite broadcasts each interval's knots to its many times: the same
    arithmetic as gathering them per time, so the same bytes."""
    from rls_addon.core.scene.motion import hermite

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 12))
    t = np.sort(rng.uniform(0, 0.1, n))
    t[0] = 0.0
    m = np.repeat(np.eye(4)[None], n, 0)
    m[:, :3, 3] = rng.normal(size=(n, 3))
    track = Track(t, m)
    q = rng.uniform(-0.01, 0.11, 20000)
    i, a, span = track._segments(q)
    p, v = track.matrices[:, :3, 3], track.velocities
    assert np.array_equal(track.positions_at(q), hermite(p[i], v[i], p[i + 1], v[i + 1], a, span))
