"""A scan's seed as recorded is the seed used: two different seeds never give one cloud,
and every seed below 2^32 gives the bytes it always gave."""

import zlib

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.errors import SettingsError
from rls_addon.core.physics.effects import scan_rng
from rls_addon.core.scan.session import ScanSession
from rls_addon.core.scan.settings import LidarSettings, ScanSettings

from .fakes import small_preset, street

BIG = [2 ** 32, 2 ** 32 + 1, 2 ** 33, 2 ** 64, 2 ** 64 + 2 ** 32, 2 ** 200]


def draws(seed, sensor="pole", frame=3):
    a, b = scan_rng(seed, sensor, frame)
    return a.random(4).tobytes() + b.random(4).tobytes()


@pytest.mark.parametrize("seed", [0, 1, 12345, 2 ** 31, 2 ** 32 - 1])
def test_seeds_below_2_32_draw_what_they_always_drew(seed):
    key = zlib.crc32(b"pole")
    old = np.random.SeedSequence([seed, key, 3]).spawn(2)
    want = b"".join(np.random.default_rng(s).random(4).tobytes() for s in old)
    assert draws(seed) == want


def test_every_seed_draws_its_own_numbers():
    seeds = [0, 1, 2 ** 32 - 1] + BIG
    got = {draws(s) for s in seeds}
    assert len(got) == len(seeds)
    # nor does a big seed of one frame or sensor repeat a small seed of another
    others = {draws(s, sensor, f) for s in (0, 1, 2 ** 32 - 1)
              for sensor in ("pole", "mast") for f in (0, 1, 3)}
    assert not ({draws(s) for s in BIG} & others)


def test_clouds_of_seeds_0_2_32_and_2_64_differ():
    preset = small_preset(noise=0.05)
    clouds = {}
    for seed in (0, 2 ** 32, 2 ** 64):
        result, info = ScanSession(NumpyCaster).scan(street(), "pole", preset,
                                                     ScanSettings(seed=seed), 1)
        assert info["seed"] == seed
        clouds[seed] = result.points.tobytes()
    assert len(set(clouds.values())) == 3


@pytest.mark.parametrize("seed", [-1, -(2 ** 32), 1.5, 7.0, "7", True, None])
def test_a_seed_that_is_not_a_whole_number_from_0_is_one_settings_error(seed):
    with pytest.raises(SettingsError) as err:
        ScanSettings(seed=seed)
    assert str(err.value) == f"the seed must be a whole number >= 0, got {seed!r}"


def test_a_negative_seed_from_an_override_is_refused():
    with pytest.raises(SettingsError, match=r"^the seed must be a whole number >= 0, got -1$"):
        LidarSettings().override(seed=-1)


def test_a_numpy_integer_seed_is_kept_as_an_int():
    seed = ScanSettings(seed=np.int64(7)).seed
    assert seed == 7 and type(seed) is int
    assert ScanSettings(seed=2 ** 70).seed == 2 ** 70
