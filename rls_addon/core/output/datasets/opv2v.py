"""OPV2V's layout for cooperative perception, as OpenCOOD reads it ("opv2v" in
``rls dataset``):

    <out>/<scenario>/<agent id>/NNNNNN.pcd    the agent LiDAR's points
    <out>/<scenario>/<agent id>/NNNNNN.yaml   its pose and the vehicles around it
    <out>/<scenario>/<agent id>/background/NNNNNN.pcd, .yaml
                                              a still agent's background sweep NNNNNN:
                                              the scene with every road user hidden

OpenCOOD (``opencood/data_utils/datasets/basedataset.py``) lists the agent folders of
a scenario sorted as text, moves the first to the end when its id is negative (a
road-side unit) and takes the first as ego (so with two road-side units or more, one
of them is ego), and per frame reads ``NNNNNN.yaml`` and ``NNNNNN.pcd``: the points with Open3D's legacy
reader and the intensity from the colour channel (``opencood/utils/pcd_utils.py:
pcd_to_np``: ``colors[:, 0]``). So each .pcd holds x y z and a packed ``rgb`` whose
three channels carry round(255 * intensity).

Everything is in CARLA's left-handed frame (``carla``: y mirrored): the points in the
LiDAR's own frame (at the sweep start, the time of ``lidar_pose``, for a LiDAR that
moves: ``points_at_sweep_start``), poses as ``[x, y, z, roll, yaw, pitch]`` in metres and degrees,
turned into matrices by OpenCOOD's ``x_to_world``. A vehicle is ``location`` (its
origin), ``center`` (from the origin to its box centre, world axes, as OpenCOOD adds
them), ``extent`` (half length, width, height), ``angle`` ([roll, yaw, pitch]) and
``speed`` (km/h, as OpenCDA logs it). ``vehicles`` holds vehicles only: OpenCOOD
(``base_postprocessor.generate_object_center``) takes every entry as a vehicle, so
other road users go under ``rls: other_objects``.

Agents: a LiDAR on a vehicle (its parent object) is that vehicle, with the vehicle's
instance id; a LiDAR on infrastructure is a road-side unit with a negative id derived
from its name (stable over runs). A frame's YAML files are written once every agent
of that frame has been scanned, since each lists the other agents' poses.
"""

import json
from pathlib import Path

import numpy as np

from .carla import carla_pose, to_carla_points
from ...errors import RLSError
from ...scene.instances import instance_id
from ..io import pcd
from ..io.atomic import atomic_write_bytes
from ..io.names import sanitize_name
from .common import (
    BackgroundSweepWriter,
    check_root,
    ensure_dir,
    frame_id,
    points_world,
    scan_settings,
    seam_notice,
    settings_differences,
    write_text,
)

KMH = 3.6
# Where a frame's points are: the LiDAR's frame at the sweep start, the frame of its
# lidar_pose (recorded with the settings: frames of older runs are scanned again)
POINTS_FRAME = "lidar_pose"
VEHICLE = "vehicle"  # the one class OPV2V's 'vehicles' holds


def rsu_id(sensor):
    """The negative agent id of a road-side LiDAR, from its name."""
    return -instance_id(f"rsu:{sensor}")


def opv2v_points(points):
    """Packed records x y z rgb (float32): sensor-frame points in CARLA's axes, the
    intensity in all three colour channels (Open3D's legacy reader gives it as
    ``colors[:, 0]`` in 0..1, to 1/255)."""
    xyz = to_carla_points(np.stack([points["x"], points["y"], points["z"]], 1))
    rec = np.empty(len(points), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<f4")])
    rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    c = np.clip(np.rint(np.asarray(points["intensity"], np.float64) * 255.0), 0, 255)
    c = c.astype(np.uint32)
    rec["rgb"] = ((c << 16) | (c << 8) | c).view(np.float32)
    return rec


def points_at_sweep_start(points, info):
    """``points`` (sensor frame, each at its own firing time) in the LiDAR's frame at the
    sweep start, the one pose OPV2V gives a point file (``lidar_pose``): OpenCOOD maps
    every point of a file by it (``basedataset.reform_param``: ``x1_to_x2(lidar_pose,
    ego lidar_pose)``), as CARLA's LiDAR, which has no motion within a tick, makes them.
    A LiDAR that moved during its sweep (its sidecar's ``sensor_poses``) has its points
    taken through the world with its pose at their own times; a still one's are as
    they are."""
    if not info.get("sensor_poses"):
        return points
    inv = np.linalg.inv(np.asarray(info["sensor_pose_start"], np.float64))
    local = points_world(points, info) @ inv[:3, :3].T + inv[:3, 3]
    out = points.copy()
    out["x"], out["y"], out["z"] = local[:, 0], local[:, 1], local[:, 2]
    return out


def vehicle_entry(box):
    """OpenCOOD's dict of one vehicle from a ground-truth box (sidecar form)."""
    centre = np.asarray(box["world"]["centre"], np.float64)
    origin = np.asarray(box["world"]["origin"], np.float64)
    pose = np.eye(4)
    pose[:3, :3] = np.asarray(box["world"]["rotation"])
    pose[:3, 3] = centre
    roll, yaw, pitch = carla_pose(pose)[3:]
    return {"location": [float(v) for v in to_carla_points(origin)[0]],
            "center": [float(v) for v in to_carla_points(centre - origin)[0]],
            "extent": [float(v) / 2 for v in box["size_lwh_m"]],
            "angle": [roll, yaw, pitch],
            "speed": float(np.linalg.norm(box["world"]["velocity_mps"]) * KMH),
            "category": box["category"], "rls_object": box["object"],
            "rls_points": int(box["points"]), "rls_time_s": float(box["time_s"])}


class Opv2vWriter:
    """The scan run's writer of the layout above (see ``run.Writer``).

    agents    {sensor name: agent id}; ``agents_for`` makes it
    carriers  {sensor name: key of the vehicle it rides on} (vehicle agents only)"""

    shardable = True  # in pieces of whole frames
    written_at_end = "the scenario's description (<scene>.rls.json) is"  # finish

    def __init__(self, root, scene_name, agents, carriers=None, overwrite=False, resume=False):
        self.root = Path(root)
        self.scene_name = scene_name
        self.scenario = self.root / sanitize_name(scene_name)
        self.agents, self.carriers = dict(agents), dict(carriers or {})
        self.overwrite, self.resume = bool(overwrite), bool(resume)
        self._pending = {}  # frame -> {sensor: yaml body without the other agents}
        self.notices = []
        self.class_types = None  # {class: [{size, objects}]}: the scene's road users

    def _dir(self, sensor):
        return self.scenario / str(self.agents[sensor])

    def path(self, sensor, output, frame):
        return self._dir(sensor) / f"{frame_id(frame)}.pcd"

    def incomplete(self, sensor, output, frame):
        """A point file whose frame's YAML was never written."""
        cloud = self.path(sensor, output, frame)
        return [cloud] if cloud.exists() and not self._yaml(sensor, frame).exists() else []

    def planned_files(self, sensor, output, frame):
        return [self.path(sensor, output, frame), self._yaml(sensor, frame)]

    def _yaml(self, sensor, frame):
        return self._dir(sensor) / f"{frame_id(frame)}.yaml"

    def check(self, sensor, output, frame):
        if sensor not in self.agents:
            raise RLSError(f"no OPV2V agent id for LiDAR '{sensor}'")
        check_root(self.root)
        frame_id(frame)
        _yaml_module()

    def existing(self, sensor, output, frame, settings=None):
        if not self.resume:
            return None
        cloud, side = self.path(sensor, output, frame), self._yaml(sensor, frame)
        if not (cloud.is_file() and side.is_file()):
            return None
        try:
            body = _yaml_module().safe_load(side.read_text())
            n = len(pcd.decode(cloud.read_bytes()))
        except Exception:  # noqa: BLE001 - anything unreadable is scanned again
            return None
        if n != body.get("rls", {}).get("points"):
            return None
        if settings is not None and settings_differences(body["rls"].get("settings"), settings,
                                                         points_frame=POINTS_FRAME):
            return None
        self._pending.setdefault(frame, {})[sensor] = body  # its pose, for the others
        self._flush(frame, written=set())
        return n

    def stale_settings(self, sensor, output, frame, settings):
        """The settings an earlier frame of ``sensor`` was written with otherwise than
        ``settings`` say (empty: the same, or no such frame)."""
        try:
            body = _yaml_module().safe_load(self._yaml(sensor, frame).read_text())
        except Exception:  # noqa: BLE001 - no readable frame: nothing to report
            return []
        rls = body.get("rls") if isinstance(body, dict) else None
        return settings_differences(rls.get("settings"), settings, points_frame=POINTS_FRAME) \
            if isinstance(rls, dict) else []

    def write(self, sensor, output, frame, points, info):
        if info.get("frame_space") != "sensor":
            raise RLSError("the OPV2V layout needs sensor-frame points")
        ensure_dir(self._dir(sensor))
        path = self.path(sensor, output, frame)
        ow = self.overwrite or self.resume
        start = np.asarray(info["sensor_pose_start"], np.float64)
        points = points_at_sweep_start(points, info)
        atomic_write_bytes(path, pcd.encode(opv2v_points(points), "binary"), overwrite=ow)
        boxes = info.get("objects", [])
        seam_notice(self.notices, sensor, boxes)
        _others_notice(self.notices, boxes)
        carrier = self.carriers.get(sensor)
        ego = next((b for b in boxes if b["object"] == carrier), None)
        lidar_pose = carla_pose(start)
        # the ego's pose at the sweep start, the time of lidar_pose (as CARLA's tick
        # gives both), not at the time the sweep passed over the car
        ego_pose = carla_pose(_box_origin_pose(ego["world_at_sweep_start"])) if ego else lidar_pose
        body = {
            "lidar_pose": lidar_pose,
            "true_ego_pos": ego_pose,
            "predicted_ego_pos": ego_pose,
            "ego_speed": float(np.linalg.norm(ego["world"]["velocity_mps"]) * KMH) if ego else 0.0,
            # OpenCOOD takes every entry of 'vehicles' as a vehicle (OPV2V has no other
            # class): the other road users are kept under 'rls'
            "vehicles": {int(b["instance"]): vehicle_entry(b) for b in boxes
                         if b["object"] != carrier and b["category"] == VEHICLE},
            "rls": {"scene": self.scene_name, "sensor": sensor, "frame": frame,
                    "other_objects": {int(b["instance"]): vehicle_entry(b) for b in boxes
                                      if b["object"] != carrier
                                      and b["category"] != VEHICLE},
                    "points": int(len(points)), "timestamp_s": info.get("timestamp_s"),
                    "agent": self.agents[sensor], "carrier": carrier,
                    "device": info.get("device", {}).get("id"),
                    "sensor_moves": bool(info.get("sensor_moves")),
                    "settings": scan_settings(info, points_frame=POINTS_FRAME)},
        }
        self._pending.setdefault(frame, {})[sensor] = body
        self._flush(frame, written={sensor})
        return path

    def background_writer(self, sweep, hidden):
        """The writer of background sweep ``sweep`` of every still agent
        (``Opv2vBackground``); ``hidden`` the source with the road users hidden."""
        return Opv2vBackground(self, sweep, hidden)

    def _flush(self, frame, written):
        """Write the frame's YAML files once every agent of it is known (scanned now or
        kept from an earlier run): each lists all agents' LiDAR poses."""
        bodies = self._pending.get(frame, {})
        if set(bodies) != set(self.agents):
            return
        poses = {str(self.agents[s]): b["lidar_pose"] for s, b in bodies.items()}
        yaml = _yaml_module()
        for sensor, body in bodies.items():
            if sensor not in written and self._yaml(sensor, frame).is_file():
                continue
            text = yaml.safe_dump(dict(body, rls=dict(body["rls"], agents=poses)),
                                  sort_keys=False)
            write_text(self._yaml(sensor, frame), text, True)
        del self._pending[frame]

    def abort(self):
        """Frames whose YAML files are written are complete; a frame cut short keeps its
        point files without YAML, which OpenCOOD does not list (--resume redoes it)."""

    def flush(self):
        """Files are written in place: nothing to wait for."""

    def _background_record(self):
        """{agent id: background sweeps} of the agents that have them (None: none)."""
        got = {str(a): len(list((self.scenario / str(a) / "background").glob("*.yaml")))
               for a in self.agents.values()}
        got = {a: n for a, n in got.items() if n}
        return {"folder": "<agent>/background", "sweeps": got,
                "what": "sweeps of the scene with every road user hidden, the device's "
                        "noise in each: the background a deployed unit learns"} if got else None

    def finish(self, run):
        """A description of the scenario beside its agent folders."""
        write_text(self.root / f"{sanitize_name(self.scene_name)}.rls.json", json.dumps({
            "layout": "OPV2V (OpenCOOD)", "scene": self.scene_name,
            "agents": {s: a for s, a in sorted(self.agents.items())},
            "carriers": self.carriers, "frames": list(run.frames),
            "background": self._background_record(), "class_types": self.class_types,
            "coordinates": "CARLA left-handed (Blender y mirrored); poses [x, y, z, roll, "
                           "yaw, pitch] in m and deg; vehicle speed km/h"}, indent=1) + "\n",
            True)


class Opv2vBackground(BackgroundSweepWriter):
    """A ``run.Writer`` of one background sweep (``scan.background_sweeps``) into each
    agent's folder: ``background/NNNNNN.pcd`` (the points as the frames') and
    ``background/NNNNNN.yaml`` (``lidar_pose`` and under ``rls`` the sweep, the scene
    frame scanned and the labels hidden). OpenCOOD lists the ``.yaml`` files of an
    agent's folder and the agent folders of a scenario: a folder inside an agent's is
    neither."""

    def _dir(self, sensor):
        return self.dataset._dir(sensor) / "background"

    def path(self, sensor, output, frame):
        return self._dir(sensor) / f"{frame_id(self.sweep)}.pcd"

    def _meta(self, sensor):
        return self._dir(sensor) / f"{frame_id(self.sweep)}.yaml"

    def write(self, sensor, output, frame, points, info):
        if info.get("frame_space") != "sensor":
            raise RLSError("the OPV2V layout needs sensor-frame points")
        path = self.path(sensor, output, frame)
        atomic_write_bytes(path, pcd.encode(opv2v_points(points), "binary"),
                           overwrite=self.overwrite)
        body = {"lidar_pose": carla_pose(np.asarray(info["sensor_pose_start"], np.float64)),
                "rls": {"scene": self.dataset.scene_name, "sensor": sensor,
                        "agent": self.dataset.agents[sensor], "sweep": self.sweep,
                        "scene_frame": frame, "points": int(len(points)),
                        **self.hidden_record(),
                        "device": info.get("device", {}).get("id"),
                        "settings": scan_settings(info)}}
        write_text(self._meta(sensor), _yaml_module().safe_dump(body, sort_keys=False),
                   self.overwrite)
        return path


def agents_for(sensors, carriers):
    """{sensor: agent id}: a vehicle-borne LiDAR gets its vehicle's instance id, a
    road-side one a negative id from its name."""
    out = {}
    for s in sensors:
        out[s] = instance_id(carriers[s]) if carriers.get(s) else rsu_id(s)
    ids = list(out.values())
    if len(set(ids)) != len(ids):
        raise RLSError("two LiDARs ride on the same vehicle; OPV2V has one LiDAR per agent: "
                       "scan them into separate datasets")
    return out


def _others_notice(notices, boxes):
    """Add (once) the notice that road users other than vehicles are not OPV2V's."""
    kinds = sorted({b["category"] for b in boxes if b["category"] != VEHICLE})
    if kinds and not any(n.startswith("OPV2V lists vehicles only") for n in notices):
        notices.append("OPV2V lists vehicles only (OpenCOOD takes every entry of a YAML's "
                       f"'vehicles' as a vehicle): the {', '.join(kinds)} boxes are under "
                       "'rls: other_objects', which OpenCOOD does not read")


def _box_origin_pose(where):
    """4x4 of a box's ``origin`` and ``rotation`` (a box dict's ``world`` or
    ``world_at_sweep_start``)."""
    m = np.eye(4)
    m[:3, :3] = np.asarray(where["rotation"])
    m[:3, 3] = where["origin"]
    return m


def _yaml_module():
    try:
        import yaml
    except ImportError:
        raise RLSError("the OPV2V layout writes YAML with PyYAML, which is not installed: "
                       "pip install pyyaml") from None
    return yaml
