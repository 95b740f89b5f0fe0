"""docs/openpcdet_custom_rls.yaml, the OpenPCDet dataset config docs/evaluate.md hands
users, agrees with what RLS's kitti layout writes and with OpenPCDet's voxel rules."""

from pathlib import Path

import pytest

from rls_addon.core.labels import OBJECT_CLASSES
from rls_addon.core.output.datasets.kitti import class_name
from tests.core.external_tools import require_module

CONFIG = Path(__file__).resolve().parents[3] / "docs" / "openpcdet_custom_rls.yaml"


@pytest.fixture(scope="module")
def config():
    yaml = require_module("yaml", "PyYAML==6.0.3")
    return yaml.safe_load(CONFIG.read_text(encoding="utf-8"))


def test_classes_features_and_splits_are_rls_own(config):
    assert config["DATASET"] == "CustomDataset"
    assert list(config["MAP_CLASS_TO_KITTI"]) == [class_name(c) for c in OBJECT_CLASSES] \
        == ["Vehicle", "Pedestrian", "Cyclist"]
    encoding = config["POINT_FEATURE_ENCODING"]
    # RLS's points/NNNNNN.npy columns (datasets/kitti.py: dataset.json point_features)
    assert encoding["src_feature_list"] == encoding["used_feature_list"] == \
        ["x", "y", "z", "intensity"]
    assert config["DATA_SPLIT"] == {"train": "train", "test": "val"}  # RLS's ImageSets
    sampling = config["DATA_AUGMENTOR"]["AUG_CONFIG_LIST"][0]
    assert sampling["NUM_POINT_FEATURES"] == 4
    assert sampling["PREPARE"]["filter_by_min_points"] == \
        ["Vehicle:5", "Pedestrian:5", "Cyclist:5"]


def test_range_and_voxels_follow_openpcdets_rules(config):
    lo_x, lo_y, lo_z, hi_x, hi_y, hi_z = config["POINT_CLOUD_RANGE"]
    voxel = next(p for p in config["DATA_PROCESSOR"]
                 if p["NAME"] == "transform_points_to_voxels")["VOXEL_SIZE"]
    # z span / voxel = 40; x and y spans / voxel a multiple of 16
    assert round((hi_z - lo_z) / voxel[2], 9) == 40
    for span, size in ((hi_x - lo_x, voxel[0]), (hi_y - lo_y, voxel[1])):
        cells = round(span / size, 9)
        assert cells == int(cells) and int(cells) % 16 == 0
    # a pole LiDAR 6-6.5 m up (level frame): the road lies inside the range's z
    assert lo_z < -6.5 and hi_z > -6.0 + 1.5
