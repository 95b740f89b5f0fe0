"""``rls dataset`` on the intersection sample scene (its traffic: vehicles at 5-17 m/s,
parked ones, pedestrians and cyclists; two LiDARs on traffic-light poles), judged by
the readers detectors use: numpy for OpenPCDet's files, Open3D's legacy reader and
PyYAML as OpenCOOD reads OPV2V."""

import json
import math

import numpy as np
import pytest

from .conftest import SCENE_SCRIPT_HEAD, build_blend, rls

FRAMES = (26, 29)
FPS = 10.0
# The sample scene's first four cars, straight: (start xy, end xy) over frames 1..60
CARS = {"Car west": ((50, 1.75), (-50, 1.75)), "Car east": ((-50, -5.25), (50, -5.25)),
        "Car north": ((1.75, -50), (1.75, 50)), "Car south": ((-5.25, 50), (-5.25, -50))}
# The rest of its traffic by the first word of a name: KITTI class and box size (l, w, h)
KINDS = {"Car": ("Vehicle", (4.5, 1.8, 1.5)), "Van": ("Vehicle", (5.2, 2.0, 2.2)),
         "Truck": ("Vehicle", (9.0, 2.5, 3.2)), "Pedestrian": ("Pedestrian", (0.6, 0.6, 1.75)),
         "Cyclist": ("Cyclist", (1.8, 0.6, 1.7))}

BUILD = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes import build_scene
from rls_addon.blender.scenes.build import mount_position
build_scene("intersection", bpy.context.scene)
scene = bpy.context.scene
for name, mount in (("Pole NE", "TL NE"), ("Pole SW", "TL SW")):
    pos = mount_position(bpy.data.objects[mount])
    lidar = bpy.data.objects.new(name, None)
    lidar.location = pos
    lidar.rotation_euler = (0.0, math.radians(10.0), math.atan2(-pos[1], -pos[0]))
    scene.collection.objects.link(lidar)
    s = lidar.rls_lidar
    s.is_lidar, s.preset_id = True, "hesai_pandar64"
    s.use_sweep_start, s.sweep_start = True, 180.0  # the seam behind, off the junction
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


@pytest.fixture(scope="module")
def junction(tmp_path_factory):
    return build_blend(tmp_path_factory.mktemp("junction"), "intersection.blend", BUILD)


def car_at(name, seconds):
    """Position and heading of a straight car at scene time ``seconds`` (frame 1 = 0 s)."""
    (x0, y0), (x1, y1) = CARS[name]
    a = seconds * FPS / 59.0
    return np.array([x0 + a * (x1 - x0), y0 + a * (y1 - y0)]), math.atan2(y1 - y0, x1 - x0)


def boxes_contain(points, box, margin):
    local = (points - box["xyz"]) @ np.array([[math.cos(box["heading"]), -math.sin(box["heading"]), 0],
                                              [math.sin(box["heading"]), math.cos(box["heading"]), 0],
                                              [0, 0, 1.0]])
    return np.all(np.abs(local) <= np.array(box["lwh"]) / 2 + margin, axis=1)


def test_kitti_layout_boxes_hold_their_cars_points(junction, tmp_path):
    from rls_addon.core.output.datasets.kitti import read_labels
    from rls_addon.core.output.io import read_cloud, read_sidecar

    out = tmp_path / "kitti"
    frames = f"{FRAMES[0]}-{FRAMES[1]}"
    proc = rls("dataset", junction, "--layout", "kitti", "--frames", frames, "--out", out,
               "--level", "--seed", "3", "--val-share", "0.5", "--split-seed", "2")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["scanned"] == 2 * (FRAMES[1] - FRAMES[0] + 1)
    # the same scans as clouds with instance ids (same seeds: the same points)
    clouds = tmp_path / "clouds"
    assert rls("scan", junction, "--frames", frames, "--out", clouds, "--seed", "3",
               "--frame-space", "sensor", "--format", "pcd_binary").returncode == 0
    ids = {}
    for sensor in ("Pole_NE", "Pole_SW"):
        root = out / sensor
        listed = sorted((root / "ImageSets" / "train.txt").read_text().split()
                        + (root / "ImageSets" / "val.txt").read_text().split())
        assert listed == [f"{f:06d}" for f in range(FRAMES[0], FRAMES[1] + 1)]
        info = json.loads((root / "dataset.json").read_text())
        assert info["class_names"] == ["Vehicle", "Pedestrian", "Cyclist"]
        # --split-seed reaches the split (seed 0 draws 26 and 28 of these four frames)
        assert info["split"] == {"val_share": 0.5, "seed": 2, "val_frames": None}
        assert (root / "ImageSets" / "val.txt").read_text().split() == ["000028", "000029"]
        checked, seen = 0, set()
        for f in range(FRAMES[0], FRAMES[1] + 1):
            pts = np.load(root / "points" / f"{f:06d}.npy")
            assert pts.dtype == np.float32 and pts.shape[1] == 4
            meta = json.loads((root / "meta" / f"{f:06d}.json").read_text())
            frame_to_world = np.array(meta["frame_to_world"])
            boxes, names = read_labels(root / "labels" / f"{f:06d}.txt")
            cloud = clouds / f"intersection_{sensor}_{f:06d}.pcd"
            scan = read_cloud(cloud)
            assert len(scan) == len(pts)
            side = read_sidecar(cloud)
            sigma = side["effects"]["noise_sigma_m"]
            for b in meta["objects"]:
                ids.setdefault(b["object"], set()).add(b["instance"])
                if not b["seen"]:
                    continue
                box = b["frame_box"]
                kind, size = KINDS[b["object"].split()[0]]
                row = [r for r in boxes if np.allclose(r[:3], box["xyz"], atol=1e-5)]
                assert len(row) == 1 and names[boxes.tolist().index(row[0].tolist())] == kind
                np.testing.assert_allclose(box["lwh"], size, atol=0.01)
                # >= 95% of the points carrying the object's instance id lie in its box
                own = (scan["instance"] == b["instance"]) & (scan["ghost"] == 0)
                inside = boxes_contain(pts[own, :3].astype(np.float64), box, 3 * sigma + 0.02)
                assert inside.mean() >= 0.95, (sensor, f, b["object"], inside.mean())
                seen.add(kind)
                if b["object"] not in CARS:
                    continue
                # heading within 0.5 deg of the animation (level frame: yaw of the sensor)
                t = (f - 1) / FPS + b["time_s"]
                centre_xy, heading = car_at(b["object"], t)
                yaw = math.atan2(frame_to_world[1, 0], frame_to_world[0, 0])
                err = (box["heading"] - (heading - yaw) + math.pi) % (2 * math.pi) - math.pi
                assert abs(math.degrees(err)) <= 0.5
                world = frame_to_world[:3, :3] @ box["xyz"] + frame_to_world[:3, 3]
                np.testing.assert_allclose(world[:2], centre_xy, atol=1e-3)
                checked += 1
        assert checked >= 8 and seen == {"Vehicle", "Pedestrian", "Cyclist"}
    assert all(len(v) == 1 for v in ids.values()) and set(CARS) < set(ids)  # one id an object
    # resuming a complete dataset scans nothing
    again = rls("dataset", junction, "--layout", "kitti", "--frames", frames, "--out", out,
                "--level", "--seed", "3", "--resume")
    assert json.loads(again.stdout)["resumed"] == summary["scanned"]


def test_opv2v_layout_reads_as_opencood_reads_it(junction, tmp_path):
    import open3d as o3d
    import yaml

    from rls_addon.core.output.datasets.carla import blender_matrix, carla_matrix

    from rls_addon.core.output.io import read_cloud

    out = tmp_path / "opv2v"
    proc = rls("dataset", junction, "--layout", "opv2v", "--frames", "27-28", "--out", out)
    assert proc.returncode == 0, proc.stderr
    clouds = tmp_path / "world"  # the same scans in world coordinates (same seeds)
    assert rls("scan", junction, "--frames", "27-28", "--out", clouds, "--frame-space", "world",
               "--format", "pcd_binary").returncode == 0
    scenario = out / "intersection"
    agents = sorted(p.name for p in scenario.iterdir())
    assert len(agents) == 2 and all(int(a) < 0 for a in agents)  # road-side units
    checked = 0
    for agent in agents:
        for f in (27, 28):
            pcd = o3d.io.read_point_cloud(str(scenario / agent / f"{f:06d}.pcd"))
            xyz = np.asarray(pcd.points)
            intensity = np.asarray(pcd.colors)[:, 0]  # OpenCOOD's pcd_to_np
            assert len(xyz) > 10_000 and 0 < intensity.max() <= 1.0
            params = yaml.safe_load((scenario / agent / f"{f:06d}.yaml").read_text())
            assert sorted(params["rls"]["agents"]) == agents
            assert len(xyz) == params["rls"]["points"]
            # points in CARLA's frame of the LiDAR: to the world (as OpenCOOD maps them)
            # and back to Blender's axes, they are the world-frame scan's points
            lidar = carla_matrix(params["lidar_pose"])
            world = xyz @ lidar[:3, :3].T + lidar[:3, 3]
            world[:, 1] *= -1
            sensor = params["rls"]["sensor"].replace(" ", "_")
            ref = read_cloud(clouds / f"intersection_{sensor}_{f:06d}.pcd")
            ref = np.stack([ref["x"], ref["y"], ref["z"]], 1)
            assert np.abs(world - ref).max() < 1e-3
            for vid, v in params["vehicles"].items():
                if v["rls_object"] not in CARS or not v["rls_points"]:
                    continue
                t = (f - 1) / FPS + v["rls_time_s"]
                xy, heading = car_at(v["rls_object"], t)
                pose = blender_matrix(v["location"] + v["angle"])  # back to Blender
                np.testing.assert_allclose(pose[:2, 3], xy, atol=1e-3)
                yaw = math.atan2(pose[1, 0], pose[0, 0])
                err = (yaw - heading + math.pi) % (2 * math.pi) - math.pi
                assert abs(math.degrees(err)) <= 0.01
                np.testing.assert_allclose(v["extent"], [2.25, 0.9, 0.75], atol=0.005)
                checked += 1
    assert checked >= 6


ROOF = SCENE_SCRIPT_HEAD + r"""
from rls_addon.blender.scenes import build_scene
build_scene("intersection", bpy.context.scene)
car = bpy.data.objects["Car west"]
lidar = bpy.data.objects.new("Roof", None)
bpy.context.scene.collection.objects.link(lidar)
lidar.parent = car
lidar.location = (0.0, 0.0, 1.9)
s = lidar.rls_lidar
s.is_lidar, s.preset_id = True, "velodyne_vlp16"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


def test_opv2v_ego_pose_and_lidar_pose_are_taken_at_one_time(tmp_path):
    """Issue 31: on a car at 17 m/s, true_ego_pos was the car where the sweep passed over
    it (up to 0.1 s in) and lidar_pose where the sweep began: 0.29 m apart. Both are now
    the sweep start, as CARLA's tick gives them."""
    import yaml

    from rls_addon.core.output.datasets.carla import carla_matrix

    blend = build_blend(tmp_path, "roof.blend", ROOF)
    out = tmp_path / "opv2v"
    proc = rls("dataset", blend, "--layout", "opv2v", "--frames", "27", "--out", out)
    assert proc.returncode == 0, proc.stderr
    agent, = (out / "intersection").iterdir()
    params = yaml.safe_load((agent / "000027.yaml").read_text())
    assert params["rls"]["carrier"] == "Car west"
    mirror = np.diag([1.0, -1.0, 1.0, 1.0])  # CARLA's y is Blender's -y
    ego = mirror @ carla_matrix(params["true_ego_pos"]) @ mirror
    lidar = mirror @ carla_matrix(params["lidar_pose"]) @ mirror
    xy, heading = car_at("Car west", (27 - 1) / FPS)  # the car at the sweep's start
    np.testing.assert_allclose(ego[:2, 3], xy, atol=1e-3)
    np.testing.assert_allclose(lidar[:3, 3], [*xy, ego[2, 3] + 1.9], atol=1e-3)
    assert params["predicted_ego_pos"] == params["true_ego_pos"]


def test_background_sweeps_are_the_scene_without_its_road_users(junction, tmp_path):
    """Issue 37: beside its frames a dataset holds each still LiDAR's sweeps of the scene
    with every road user hidden (parked cars too), the device's noise in each, in the
    frames' own format and frame: what a deployed unit's background holds. Of their
    points at most a handful lie in a vehicle's, pedestrian's or cyclist's box of the
    frame they were scanned at (a glossy facade's ghost lands where its bounce takes
    it), where the frame itself has thousands."""
    import yaml

    out = tmp_path / "kitti"
    proc = rls("dataset", junction, "--layout", "kitti", "--frames", "27-28", "--out", out,
               "--background-sweeps", "3", "--level")  # boxes upright in the points' frame
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)["background"]
    assert summary["sweeps"] == 3 and summary["scene_frame"] == 27
    assert sorted(summary["sensors"]) == ["Pole NE", "Pole SW"]
    for sensor in ("Pole_NE", "Pole_SW"):
        root = out / sensor
        about = json.loads((root / "dataset.json").read_text())
        assert about["background"]["sweeps"] == 3
        # the scene's own types of road users (the sizes its objects are modelled at),
        # the commonest first: the car
        types = about["class_types"]
        assert {n: {tuple(t["size"]) for t in types[n]} for n in types} == {
            "vehicle": {KINDS[k][1] for k in ("Car", "Van", "Truck")},
            "pedestrian": {KINDS["Pedestrian"][1]}, "cyclist": {KINDS["Cyclist"][1]}}
        assert types["vehicle"][0]["size"] == list(KINDS["Car"][1])
        frame = json.loads((root / "meta" / "000027.json").read_text())
        boxes = [b["frame_box"] for b in frame["objects"]]
        own = np.load(root / "points" / "000027.npy")[:, :3]
        def inside(p):  # in a box, clear of its bottom face (the road under it, its noise)
            return sum(int((boxes_contain(p, b, 0.05)
                            & (p[:, 2] > b["xyz"][2] - b["lwh"][2] / 2 + 0.15)).sum())
                       for b in boxes)

        assert inside(own) > 1000
        sweeps = [np.load(root / "background" / "points" / f"{k:06d}.npy") for k in range(3)]
        for k, pts in enumerate(sweeps):
            meta = json.loads((root / "background" / "meta" / f"{k:06d}.json").read_text())
            assert meta["scene_frame"] == 27 and meta["sweep"] == k and meta["objects"] == []
            assert meta["hidden_labels"] == ["cyclist", "pedestrian", "vehicle"]
            assert meta["frame_to_world"] == frame["frame_to_world"]
            assert len(pts) == meta["points"] > 10_000 and inside(pts[:, :3]) <= 5
        assert sweeps[0].tobytes() != sweeps[1].tobytes()  # each sweep its own noise
    # OPV2V: in each agent's folder, where OpenCOOD lists neither
    out = tmp_path / "opv2v"
    proc = rls("dataset", junction, "--layout", "opv2v", "--frames", "27", "--out", out,
               "--background-sweeps", "2")
    assert proc.returncode == 0, proc.stderr
    for agent in (out / "intersection").iterdir():
        names = sorted(p.name for p in (agent / "background").iterdir())
        assert names == ["000000.pcd", "000000.yaml", "000001.pcd", "000001.yaml"]
        body = yaml.safe_load((agent / "background" / "000001.yaml").read_text())
        assert body["rls"]["sweep"] == 1 and body["rls"]["scene_frame"] == 27
        assert sorted(p.name for p in agent.glob("*.yaml")) == ["000027.yaml"]
