"""The detector over kitti-layout datasets (``evaluate/detect_dataset.py``): a frame's
points go back to their sensor's own frame whichever frame the dataset wrote them in."""

import math

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.detect_dataset import (DEFAULT_NOISE_SIGMA_M, detect_datasets,
                                                    frame_points, noise_sigma_of)
from rls_addon.core.evaluate.kitti_meta import KittiMeta

from .builders import kitti_dataset, points, pose


@pytest.mark.parametrize("level", [False, True])
def test_points_come_back_in_the_sensor_frame(tmp_path, level):
    """A pitched, yawed sensor: with --level the dataset holds the points in a
    gravity-aligned frame; either way they come back as the sensor saw them."""
    sensor = pose(5.0, -3.0, 6.0, yaw=0.7, pitch=math.radians(15))
    root = kitti_dataset(tmp_path, sensor, level=level)
    meta = KittiMeta.open(root)
    want = np.stack([points()[c] for c in "xyz"], 1).astype(np.float64)
    got = frame_points(meta, 1)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, atol=2e-5)  # the dataset's float32
    if level:  # the file itself is not in the sensor frame
        stored = np.load(root / "points" / "000001.npy")[:, :3]
        assert np.abs(stored - want).max() > 0.1


def test_noise_comes_from_the_devices_preset_or_the_default(tmp_path):
    meta = KittiMeta.open(kitti_dataset(tmp_path, pose(z=5.0)))  # device 'small8': unknown
    assert noise_sigma_of(meta) == DEFAULT_NOISE_SIGMA_M


def test_bad_input_is_one_clear_error(tmp_path):
    a = kitti_dataset(tmp_path / "a", pose(z=5.0), frames=(1, 2))
    b = kitti_dataset(tmp_path / "b", pose(z=5.0), frames=(3,))
    with pytest.raises(InputError, match="name one sensor twice"):
        detect_datasets([a, a])
    with pytest.raises(InputError, match="background frames \\[7\\]"):
        detect_datasets([a], "frames", background_frames=[7])
    with pytest.raises(InputError, match="no background sweeps .*--background frames"):
        detect_datasets([a])  # written without sweeps: the empty scene's are not there
    with pytest.raises(InputError, match="go with --background frames"):
        detect_datasets([kitti_dataset(tmp_path / "c", pose(z=5.0), sweeps=2)],
                        background_frames=[1])
    (tmp_path / "b" / "lidar").rename(tmp_path / "b" / "other")
    with pytest.raises(InputError, match="share no frame"):
        detect_datasets([a, tmp_path / "b" / "other"])
    (a / "points" / "000002.npy").unlink()
    with pytest.raises(InputError, match="frame 2 has meta but no points"):
        detect_datasets([a], "frames")


def test_the_background_is_the_stored_sweeps_by_default_and_says_so(tmp_path):
    """The dataset's background/ sweeps (the scene without road users) are what the
    detector learns unless told to learn from the frames; what it learned is returned
    to be said in the output."""
    root = kitti_dataset(tmp_path, pose(z=5.0), frames=(1, 2, 3), sweeps=3)
    _, frames, timing = detect_datasets([root])
    assert frames == [1, 2, 3]
    assert timing["background"]["kind"] == "empty"
    assert timing["background"]["sweeps"] == {"lidar": 3}
    assert timing["background"]["hidden_labels"] == ["cyclist", "pedestrian", "vehicle"]
    _, _, timing = detect_datasets([root], "frames", [2, 3])
    assert timing["background"]["kind"] == "frames" and timing["background"]["frames"] == [2, 3]
    with pytest.raises(Exception, match="detector background"):
        detect_datasets([root], "yesterday")
