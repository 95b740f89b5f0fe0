"""Ground-truth boxes, stable ids, visibility and sensor poses, against a fake scene
whose objects move by known functions (no Blender)."""

import math

import numpy as np
import pytest

from rls_addon.core.scene.instances import check_ids, instance_id
from rls_addon.core.scene.motion import poses_at
from rls_addon.core.scan.run import ScanRun, SensorJob
from rls_addon.core.scan.settings import LidarSettings, OutputSettings, ScanSettings

from .fakes import FakeScene, numpy_factory, small_preset, translation

V = 15.0  # m/s


def yawed(p, yaw):
    m = translation(p)
    c, s = math.cos(yaw), math.sin(yaw)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def scene(occluder=False, sensor_speed=0.0):
    """A ground, a car (4.5 x 1.8 x 1.5 m, heading 30 deg) driving at V along its
    heading past a pole sensor; optionally a wall between them; a parked cyclist."""
    heading = math.radians(30.0)
    u = np.array([math.cos(heading), math.sin(heading), 0.0])
    boxes = {"ground": ((-60, -60, -1.2), (60, 60, -1.0), 1),
             "car": ((-2.25, -0.9, 0.0), (2.25, 0.9, 1.5), 11),
             "bike": ((-0.9, -0.3, 0.0), (0.9, 0.3, 1.7), 18)}
    motion = {"car": lambda s: yawed(np.array([6.0, -9.0, -1.0]) + V * s * u, heading),
              "bike": lambda s: yawed((-6.0, 7.0, -1.0), 1.0)}
    if occluder:
        boxes["wall"] = ((2.0, -8.0, -1.0), (2.3, 0.0, 3.0), 4)
    sensors = {"pole": lambda s: translation((0.0, 0.0, 2.0) + np.array([sensor_speed * s, 0, 0])),
               "mast": lambda s: translation((14.0, -3.0, 3.0))}
    sc = FakeScene(boxes, sensors, motion)
    if sensor_speed:
        sc.moving_sensors = {"pole"}
    return sc, heading, u


def scan(sc, frames=(1,), sensors=("pole",), **scan_kw):
    got = {}
    preset = small_preset(steps=1800, noise=0.01)
    jobs = [SensorJob(n, LidarSettings(scan=ScanSettings(**scan_kw),
                                       output=OutputSettings()), preset) for n in sensors]
    ScanRun(sc, jobs, list(frames), factory=numpy_factory,
            on_result=lambda j, f, r, i: got.update({(j.name, f): (r, i)})).run()
    return got


def test_car_box_has_its_size_heading_and_velocity_and_holds_its_points():
    sc, heading, u = scene()
    (result, info), = scan(sc, frames=(2,)).values()
    boxes = {b["object"]: b for b in info["objects"]}
    assert set(boxes) == {"car", "bike"} and info["object_classes"] == [11, 12, 18]
    car = boxes["car"]
    assert car["instance"] == instance_id("car") and car["category"] == "vehicle"
    np.testing.assert_allclose(car["size_lwh_m"], [4.5, 1.8, 1.5], atol=1e-9)
    assert car["world"]["heading_rad"] == pytest.approx(heading, abs=1e-9)
    np.testing.assert_allclose(car["world"]["velocity_mps"], V * u, atol=1e-6)
    # the box stands where the car was at the box's own time
    t = sc.seconds(2, car["time_s"])
    centre = np.array([6.0, -9.0, -1.0]) + V * t * u + [0, 0, 0.75]
    np.testing.assert_allclose(car["world"]["centre"], centre, atol=1e-9)
    # ... which is when the sensor saw it: its points lie in the box
    pts = result.points
    own = (pts["instance"] == car["instance"]) & (pts["ghost"] == 0)
    assert car["seen"] and car["points"] == own.sum() > 50
    assert car["points_in_box"] >= 0.95 * car["points"]
    assert car["visible_share"] == pytest.approx(1.0)
    # sensor frame: the pole does not turn, so only the centre moves
    np.testing.assert_allclose(car["sensor"]["centre"], centre - [0, 0, 2.0], atol=1e-9)
    assert car["sensor"]["heading_rad"] == pytest.approx(heading, abs=1e-9)


def test_an_occluded_car_is_listed_with_no_points_and_no_visibility():
    sc, _, _ = scene(occluder=True)
    got = scan(sc, frames=(1,), sensors=("pole", "mast"))
    pole = {b["object"]: b for b in got[("pole", 1)][1]["objects"]}
    mast = {b["object"]: b for b in got[("mast", 1)][1]["objects"]}
    assert pole["car"]["instance"] == mast["car"]["instance"]  # the same id in every sensor
    hidden, seen = pole["car"], mast["car"]
    assert not hidden["seen"] and hidden["points"] == 0 and hidden["rays_on_box"] > 20
    assert hidden["visible_share"] == 0.0  # rays cross its box but the wall stops them
    assert seen["seen"] and seen["visible_share"] > 0.9


def test_a_car_out_of_view_is_still_listed_flagged():
    sc, _, _ = scene()
    sc.boxes["ground"] = ((-200, -200, -1.2), (200, 200, -1.0), 1)
    sc.motion["car"] = lambda s: translation((60.0, 50.0, -1.0))  # beyond the 60 m range
    (result, info), = scan(sc).values()
    car = {b["object"]: b for b in info["objects"]}["car"]
    assert not car["seen"] and car["points"] == 0 and car["visible_share"] is None


def test_snapshot_boxes_stand_still_and_match_the_frozen_scene():
    sc, heading, u = scene()
    (result, info), = scan(sc, frames=(3,), motion="snapshot").values()
    car = {b["object"]: b for b in info["objects"]}["car"]
    centre = np.array([6.0, -9.0, -1.0]) + V * sc.seconds(3) * u + [0, 0, 0.75]
    np.testing.assert_allclose(car["world"]["centre"], centre, atol=1e-9)
    assert car["points_in_box"] >= 0.95 * car["points"] > 50


def test_moving_sensor_poses_map_its_sensor_frame_cloud_onto_the_scene():
    """Sensor at 20 m/s: the sidecar's knots give each point's pose at its own time,
    and the mapped points lie on the ground slab's top within 1 cm."""
    sc, _, _ = scene(sensor_speed=20.0)
    sc.motion.clear()
    (result, info), = scan(sc, frames=(2,), noise=False).values()
    assert info["sensor_moves"] and len(info["sensor_poses"]["times_s"]) >= 2
    knots = info["sensor_poses"]
    pts = result.points
    ground = pts["label"] == 1
    poses = poses_at(knots["times_s"], knots["matrices"], pts["time"][ground])
    local = np.stack([pts["x"], pts["y"], pts["z"]], 1)[ground]
    world = np.einsum("nij,nj->ni", poses[:, :3, :3], local) + poses[:, :3, 3]
    assert len(world) > 1000 and np.abs(world[:, 2] - (-1.0)).max() <= 0.01
    # with only the sweep-start pose the same points are up to v*T = 2 m off
    start = np.asarray(info["sensor_pose_start"])
    naive = local @ start[:3, :3].T + start[:3, 3]
    assert np.abs(naive[:, 0] - world[:, 0]).max() > 1.5
    end = np.asarray(info["sensor_pose_end"])
    assert end[0, 3] - start[0, 3] == pytest.approx(20.0 * 0.1, abs=1e-6)


def test_instance_ids_are_stable_and_collisions_are_reported():
    assert instance_id("Car west") == instance_id("Car west") > 0
    assert instance_id("Car west") != instance_id("Car east")
    assert check_ids({5: {"a"}, 7: {"b", "c"}}) == [
        "objects b, c share instance id 7: rename one of them to tell their points apart"]


def test_no_ground_truth_when_switched_off_and_none_without_objects():
    sc, _, _ = scene()
    preset = small_preset()
    got = {}
    off = SensorJob("pole", LidarSettings(output=OutputSettings(ground_truth=False)), preset)
    ScanRun(sc, [off], [1], factory=numpy_factory,
            on_result=lambda j, f, r, i: got.update(info=i)).run()
    assert "objects" not in got["info"] and got["info"]["label_names"]["18"] == "cyclist"
    del sc.boxes["car"], sc.boxes["bike"]
    sc.motion.clear()
    ScanRun(sc, [SensorJob("pole", LidarSettings(), preset)], [1], factory=numpy_factory,
            on_result=lambda j, f, r, i: got.update(info=i)).run()
    assert got["info"]["objects"] == []


def test_boxes_worked_out_behind_the_scan_are_the_boxes_and_their_errors_surface(
        tmp_path, monkeypatch):
    """A writer that writes behind the scan gets the boxes as a ``Later`` and works
    them out on its thread, just before the frame's files (rls scan, rls dataset): the
    same boxes as worked out in the scan (a run with previews), the same files written
    behind or not; a box that cannot be worked out fails the run at its frame, and that
    frame leaves no file."""
    import json

    from rls_addon.core.output.io import behind, read_sidecar
    from rls_addon.core.output.io.writer import CloudWriter
    from rls_addon.core.scan import session

    preset = small_preset(steps=1800, noise=0.01)

    def run(out, background=True, on_result=None):
        sc, _, _ = scene(sensor_speed=10.0)
        jobs = [SensorJob("pole", LidarSettings(scan=ScanSettings(), output=OutputSettings(
            directory=str(out))), preset)]
        writer = CloudWriter(sc.name, background=background)
        return ScanRun(sc, jobs, [1, 2], writer=writer, factory=numpy_factory,
                       on_result=on_result).run()

    handed = []
    write = CloudWriter.write

    def spy(self, sensor, output, frame, points, info):
        handed.append(type(info["objects"]))
        return write(self, sensor, output, frame, points, info)

    monkeypatch.setattr(CloudWriter, "write", spy)
    seen = {}
    run(tmp_path / "now", on_result=lambda j, f, r, i: seen.update({f: i["objects"]}))
    assert handed == [list, list]  # a run that shows its results works them out at once
    handed.clear()
    for background in (True, False):
        run(tmp_path / str(background), background=background)
    assert handed == [behind.Later] * 4
    for frame in (1, 2):
        name = f"fake_pole_{frame:06d}.pcd"
        side = read_sidecar(tmp_path / "True" / name)
        assert side["objects"] == json.loads(json.dumps(seen[frame]))
        assert {b["object"] for b in side["objects"]} == {"car", "bike"}
        for other in ("now", "False"):
            for f in (name, name.replace(".pcd", ".json")):
                assert (tmp_path / "True" / f).read_bytes() == (tmp_path / other / f).read_bytes()

    boxes, calls = session.object_boxes, []

    def fails_at_frame_2(*args):
        calls.append(args)
        if len(calls) == 2:
            raise ValueError("no box today")
        return boxes(*args)

    monkeypatch.setattr(session, "object_boxes", fails_at_frame_2)
    with pytest.raises(ValueError, match="no box today"):
        run(tmp_path / "failed")
    assert sorted(p.name for p in (tmp_path / "failed").iterdir()) == [
        "fake_pole_000001.json", "fake_pole_000001.pcd"]
