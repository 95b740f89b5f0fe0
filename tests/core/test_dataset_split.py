"""The dataset's train/val split (``core/output/datasets/common.Split``): a seeded share
of the frames, the same for a seed and another for another seed, or a frame range."""

import pytest

from rls_addon.core.errors import SettingsError
from rls_addon.core.output.datasets.common import Split

IDS = [f"{i:06d}" for i in range(1, 41)]


def test_the_same_seed_gives_the_same_split_and_other_seeds_others():
    splits = {seed: Split(0.25, seed).val(IDS) for seed in range(8)}
    for seed, val in splits.items():
        assert len(val) == 10 and set(val) <= set(IDS) and val == sorted(val)
        assert Split(0.25, seed).val(list(reversed(IDS))) == val  # the order given does not count
    # 40 frames choose 10 in 8.5e8 ways: eight seeds drawing one split would be the seed ignored
    assert len({tuple(v) for v in splits.values()}) == 8


def test_share_range_and_limits():
    assert Split(0.0, 3).val(IDS) == []
    assert Split(0.5, 3, val_frames=(5, 8)).val(IDS) == ["000005", "000006", "000007", "000008"]
    assert Split(0.5, 3).to_dict() == {"val_share": 0.5, "seed": 3, "val_frames": None}
    for bad in (1.0, -0.1):
        with pytest.raises(SettingsError, match="validation share"):
            Split(bad)
