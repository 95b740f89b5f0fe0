"""OPV2V's YAML as OpenCOOD reads it (DerrickXuNu/OpenCOOD, main of 2024-08-16):
``opencood/data_utils/post_processor/base_postprocessor.py`` ``generate_object_center``
merges every agent's ``params['vehicles']`` and ``box_utils.project_world_objects``
turns each entry into a ground-truth box of the one class OPV2V has; no entry's
category is read."""

import numpy as np
import yaml

from rls_addon.core.output.datasets.opv2v import Opv2vWriter, agents_for

from .evaluate.builders import OBJECTS, VEHICLE, info, object_boxes, points, pose

EGO = pose(5.0, 2.0, 1.9, yaw=0.3)
RSU = pose(0.0, -8.0, 6.0, yaw=0.2, pitch=0.17)


def test_vehicles_lists_vehicles_only(tmp_path):
    """A pedestrian or cyclist among 'vehicles' is a car to OpenCOOD: the walker and the
    bike of the builders' scene were listed there (and trained on as vehicles)."""
    carriers = {"roof": "car"}
    writer = Opv2vWriter(tmp_path, "scene", agents_for(["roof", "pole"], carriers), carriers)
    for sensor, p in (("roof", EGO), ("pole", RSU)):
        writer.write(sensor, None, 3, points(), info(p, object_boxes(p)))
    names = {100 + k: (name, label) for k, (name, label, *_) in enumerate(OBJECTS)}
    for agent in writer.scenario.iterdir():
        body = yaml.safe_load((agent / "000003.yaml").read_text())
        carrier = body["rls"]["carrier"]
        want = {i for i, (n, label) in names.items() if label == VEHICLE and n != carrier}
        assert set(body["vehicles"]) == want
        assert all(v["category"] == "vehicle" for v in body["vehicles"].values())
        others = body["rls"]["other_objects"]
        assert sorted(v["rls_object"] for v in others.values()) == ["bike", "walker"]
        np.testing.assert_allclose(others[101]["extent"], [0.3, 0.3, 0.9])
    assert sum(n.startswith("OPV2V lists vehicles only") for n in writer.notices) == 1
