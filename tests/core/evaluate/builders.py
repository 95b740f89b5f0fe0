"""Small RLS datasets for the readers' tests, written by RLS's own writers from fake
scans: a few upright boxes of known world poses seen by a still or moving sensor."""

import math

import numpy as np

from rls_addon.core.output.datasets.kitti import KittiWriter
from rls_addon.core.output.datasets.opv2v import Opv2vWriter, agents_for
from rls_addon.core.output.ground_truth import ObjectBox
from rls_addon.core.points import empty_points

VEHICLE, PEDESTRIAN, CYCLIST = 11, 12, 18


def pose(x=0.0, y=0.0, z=0.0, yaw=0.0, pitch=0.0, roll=0.0):
    """4x4 world pose: Rz(yaw) Ry(pitch) Rx(roll) (radians; pitch > 0 noses down)."""
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    m[:3, 3] = (x, y, z)
    return m


# (name, label, centre, size lwh, yaw, points)
OBJECTS = [
    ("car", VEHICLE, (12.0, 3.0, 0.8), (4.5, 1.9, 1.6), 0.4, 120),
    ("walker", PEDESTRIAN, (8.0, -4.0, 0.9), (0.6, 0.6, 1.8), -2.0, 30),
    ("bike", CYCLIST, (20.0, 6.0, 0.85), (1.8, 0.6, 1.7), 2.9, 12),
    ("hidden_car", VEHICLE, (30.0, -9.0, 0.75), (4.2, 1.8, 1.5), -0.7, 0),
]


def object_boxes(sensor_pose, shift=(0.0, 0.0, 0.0), objects=OBJECTS):
    """Sidecar dicts (``ObjectBox.to_dict``) of ``objects`` moved by ``shift``."""
    out = []
    for k, (name, label, centre, size, yaw, points) in enumerate(objects):
        p = pose(*(np.asarray(centre) + shift), yaw=yaw)
        origin = p[:3, 3] - np.array([0.0, 0.0, size[2] / 2])
        still = p.copy()  # the object's matrix: standing still over the sweep
        still[:3, 3] = origin
        box = ObjectBox(100 + k, name, label, np.array(size, float), p, 0.05, np.zeros(3),
                        np.asarray(sensor_pose, float), origin, points=points,
                        points_in_box=points, visible_share=0.5 if points else math.nan,
                        start_matrix=still)
        out.append(box.to_dict())
    return out


def points(n=5):
    pts = empty_points(n)
    pts["x"] = np.linspace(2, 10, n)
    pts["intensity"] = 0.5
    pts["time"] = np.linspace(0.0, 0.09, n)
    return pts


def info(sensor_pose, objects, knots=None):
    out = {"frame_space": "sensor", "sensor_pose_start": np.asarray(sensor_pose).tolist(),
           "sensor_to_world": np.asarray(sensor_pose).tolist(), "objects": objects,
           "timestamp_s": 0.0, "device": {"id": "small8"}}
    if knots is not None:
        out["sensor_poses"] = knots
    return out


class _Hidden:
    """What ``scene.hidden.WithoutLabels`` tells a background writer."""
    label_ids = frozenset({VEHICLE, PEDESTRIAN, CYCLIST})
    hidden = {"car", "walker"}


def kitti_dataset(root, sensor_pose, level=False, frames=(1, 2), moving=False, sweeps=0,
                  scene="scene"):
    """An RLS kitti dataset of sensor 'lidar' of scene ``scene`` under ``root``: per
    frame the objects moved 1 m along x per frame; ``moving``: the sensor drives 1.5 m
    along its sweep; ``sweeps`` background sweeps (the points, no objects). Returns the
    sensor root."""
    writer = KittiWriter(root, scene, level=level)
    for k in range(sweeps):
        writer.background_writer(k, _Hidden()).write(
            "lidar", None, frames[0], points(), info(np.asarray(sensor_pose, float), []))
    for f in frames:
        start = np.asarray(sensor_pose, float)
        knots = None
        if moving:
            end = start.copy()
            end[:3, 3] += (1.5, 0.0, 0.0)
            knots = {"times_s": [0.0, 0.1], "matrices": [start.tolist(), end.tolist()]}
        boxes = object_boxes(start, shift=(float(f), 0.0, 0.0))
        writer.write("lidar", None, f, points(), info(start, boxes, knots))
    return writer.sensor_root("lidar")


def opv2v_dataset(root, ego_pose, rsu_pose, frames=(3, 4), scene="scene"):
    """An RLS OPV2V dataset: LiDAR 'roof' on vehicle 'ego_car' (the ego) and road-side
    LiDAR 'pole'. Returns (scenario folder, {frame: world boxes of the vehicles the
    ego's YAML lists (its vehicles but its carrier: OPV2V lists vehicles only)})."""
    carriers = {"roof": "ego_car"}
    writer = Opv2vWriter(root, scene, agents_for(["roof", "pole"], carriers), carriers)
    ego_obj = ("ego_car", VEHICLE, tuple(np.asarray(ego_pose)[:3, 3] - (0, 0, 1.0)),
               (4.6, 1.9, 1.5), math.atan2(ego_pose[1][0], ego_pose[0][0]), 0)
    truth = {}
    for f in frames:
        shift = (float(f), 0.0, 0.0)
        for sensor, p in (("roof", ego_pose), ("pole", rsu_pose)):
            boxes = object_boxes(p, shift, OBJECTS + [ego_obj])
            writer.write(sensor, None, f, points(), info(p, boxes))
        truth[f] = np.array([[*(np.asarray(c) + shift), *s, y] for _, label, c, s, y, _
                             in OBJECTS if label == VEHICLE])
    return writer.scenario, truth
