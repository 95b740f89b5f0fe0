"""The scan run's orchestration with a fake scene source and the numpy caster: no
Blender, milliseconds a test. Files, seeds, resume, cancel, progress, caching, motion
decisions and errors, as every entry point (UI, command line, demo) gets them."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.errors import OutputError, SceneError, SettingsError
from rls_addon.core.output.io import read_cloud, read_records, read_sidecar
from rls_addon.core.output.io.writer import CloudWriter
from rls_addon.core.scan.run import ScanRun, SensorJob
from rls_addon.core.scan.settings import LidarSettings, OutputSettings, ScanSettings

from .fakes import numpy_factory, small_preset, street

PRESET = small_preset()


def job(name, out=None, **scan):
    settings = LidarSettings(preset=PRESET.id, scan=ScanSettings(noise=False, **scan),
                             output=OutputSettings(directory=str(out or "unused")))
    return SensorJob(name, settings, PRESET)


def run_of(scene, jobs, frames, out=None, **kw):
    writer = CloudWriter(scene.name, **kw.pop("writer_kw", {})) if out is not None else None
    return ScanRun(scene, jobs, frames, writer=writer, factory=numpy_factory, **kw)


def test_frames_by_sensors_write_clouds_and_sidecars(tmp_path):
    scene = street()
    steps = []
    run = run_of(scene, [job("pole", tmp_path), job("mast", tmp_path)], [1, 2], tmp_path,
                 progress=steps.append).run()
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted([f"fake_{s}_{f:06d}.{e}" for s in ("pole", "mast") for f in (1, 2)
                            for e in ("pcd", "json")] + ["fake_instances.json"])
    table = json.loads((tmp_path / "fake_instances.json").read_text())
    assert {v["object"] for v in table["instances"].values()} == {"ground", "wall", "car"}
    assert table["label_names"]["11"] == "vehicle"
    assert [(s.frame, s.sensor, s.done, s.total) for s in steps] == [
        (1, "pole", 1, 4), (1, "mast", 2, 4), (2, "pole", 3, 4), (2, "mast", 4, 4)]
    assert steps[-1].eta_s == 0.0 and all(s.points > 500 for s in steps)
    side = read_sidecar(tmp_path / "fake_pole_000001.pcd")
    assert side["sensor"] == "pole" and side["frame"] == 1 and side["points"] == steps[0].points
    assert side["format"] == "pcd_binary" and side["backend"] == "numpy"
    assert len(read_cloud(tmp_path / "fake_pole_000001.pcd")) == steps[0].points
    s = run.summary()
    assert (s["scanned"], s["resumed"], s["cancelled"]) == (4, 0, False)
    assert s["points"] == sum(x.points for x in steps) and len(s["outputs"]) == 4
    assert run.frames_done == [1, 2] and scene.frame == 1  # put back where it was
    json.dumps(s)


def test_a_sensor_is_written_as_its_output_settings_say(tmp_path):
    scene = street()
    j = job("pole", tmp_path)
    j = SensorJob("pole", j.settings.override(format="ply_binary",
                                              fields=("x", "y", "z", "range", "ring"),
                                              template="{sensor}/{frame:03d}"), PRESET)
    run_of(scene, [j], [3], tmp_path).run()
    rec = read_records(tmp_path / "pole" / "003.ply")
    assert rec.dtype.names == ("x", "y", "z", "range", "ring")
    r = np.sqrt(rec["x"].astype(float) ** 2 + rec["y"] ** 2 + rec["z"] ** 2)
    assert np.abs(r - rec["range"]).max() < 1e-3


def test_seeds_come_from_seed_sensor_and_frame():
    scene = street()
    noisy = [SensorJob(n, LidarSettings(scan=ScanSettings(seed=3)), small_preset(noise=0.02))
             for n in ("pole", "mast")]
    a = run_of(scene, noisy, [1, 2]).run()
    b = run_of(scene, noisy[:1], [2]).run()  # the same scan alone, in another run
    pts = {}

    def keep(job, frame, result, info):
        pts[(job.name, frame)] = result.points.tobytes()

    run_of(scene, noisy, [1, 2], on_result=keep).run()
    again = {}
    run_of(scene, noisy[:1], [2], on_result=lambda j, f, r, i: again.update(
        {(j.name, f): r.points.tobytes()})).run()
    assert again[("pole", 2)] == pts[("pole", 2)]       # same inputs, same bytes
    assert pts[("pole", 1)] != pts[("pole", 2)]          # another frame, other draws
    assert a.points and b.points


def test_a_still_sensor_prepares_its_scene_once_and_reuses_its_cast():
    scene = street()
    stats, infos = [], []
    run = run_of(scene, [job("pole")], [1, 2, 3],
                 on_result=lambda j, f, r, i: (stats.append(r.stats), infos.append(i))).run()
    assert run.structure_builds == 1
    assert [s["static_cast_reused"] for s in stats] == [False, True, True]
    # how the run went is not what it wrote: a sharded run's sidecars are the same bytes
    assert not any("static_cast_reused" in i for i in infos)


def test_a_moving_car_is_cast_exactly_in_its_own_frame():
    v = 15.0
    scene = street(car_speed=v)
    got = []
    run_of(scene, [job("pole", frame_space="world")], [2],
           on_result=lambda j, f, r, i: got.append((r, i))).run()
    result, info = got[0]
    assert info["motion"]["rigid"] == ["car"] and info["effects"]["substeps_used"] is None
    p = result.points[result.points["label"] == 11]
    assert len(p) > 20
    y0 = -8.0 + v * scene.seconds(2, p["time"])  # the car's centre at each ray's time
    # every car point lies on the car where it was at the point's own time
    inside_y = np.abs(p["y"] - y0) <= 0.9 + 1e-6
    on_x = np.minimum(np.abs(p["x"] - 1.75), np.abs(p["x"] - 6.25)) <= 1e-6
    on_face = np.isclose(np.abs(p["y"] - y0), 0.9, atol=1e-6) | np.isclose(p["z"], 0.5, atol=1e-6)
    assert np.all(inside_y & (on_x | on_face))


def test_adaptive_substeps_are_chosen_from_the_motion_and_recorded():
    """motion 'substeps' with N = 0: enough sub-steps that nothing moves more than the
    tolerance (the preset's noise, else 1 cm) within one; the sidecar says which N."""
    v = 12.0
    scene = street(car_speed=v)
    got = []
    run_of(scene, [job("pole", motion="substeps", substeps=0)], [1],
           on_result=lambda j, f, r, i: got.append((r, i))).run()
    result, info = got[0]
    travel = v * PRESET.period  # the car's box moves this far in one sweep
    want = min(64, math.ceil(travel / 0.01))
    assert info["effects"]["substeps"] == 0 and info["effects"]["substeps_used"] == want
    assert result.stats["substeps_used"] == want
    # scan_frame on its own (no session) decides the same N from the bodies it is given
    from rls_addon.core.scan.sweep import adaptive_substeps

    fixed = []
    run_of(scene, [job("pole", motion="substeps", substeps=5)], [1],
           on_result=lambda j, f, r, i: fixed.append(i)).run()
    assert fixed[0]["effects"]["substeps_used"] == 5
    still = []
    run_of(street(), [job("pole", motion="substeps")], [1],
           on_result=lambda j, f, r, i: still.append(i)).run()
    assert still[0]["effects"]["substeps_used"] == 1  # nothing moves: one sweep
    assert adaptive_substeps([], None, 0.01) == 1


def test_cancel_is_asked_after_the_frame_is_set_and_leaves_complete_files(tmp_path):
    scene = street()
    run = run_of(scene, [job("pole", tmp_path), job("mast", tmp_path)], [1, 2, 3], tmp_path,
                 cancelled=lambda: scene.frame == 2)
    run.run()
    assert run.cancelled and run.frames_done == [1] and run.index == 2
    assert len(list(tmp_path.glob("*.pcd"))) == 2 and len(list(tmp_path.glob("*.json"))) == 2
    assert scene.frame == 1


def test_resume_keeps_finished_outputs_and_redoes_broken_ones(tmp_path):
    scene = street()
    jobs = [job("pole", tmp_path)]
    run_of(scene, jobs, [1, 2, 3], tmp_path).run()
    (tmp_path / "fake_pole_000002.json").unlink()
    cloud = tmp_path / "fake_pole_000003.pcd"
    cloud.write_bytes(cloud.read_bytes()[:200])
    with pytest.raises(OutputError, match="already exists"):
        run_of(scene, jobs, [1, 2, 3], tmp_path).run()
    again = run_of(scene, jobs, [1, 2, 3, 4], tmp_path, writer_kw={"resume": True}).run()
    assert (again.resumed, again.scanned) == (1, 3)
    assert [o.resumed for o in again.outputs] == [True, False, False, False]
    for f in (1, 2, 3, 4):
        p = tmp_path / f"fake_pole_{f:06d}.pcd"
        assert len(read_cloud(p)) == read_sidecar(p)["points"]


def test_a_resumed_run_writes_the_instance_table_of_an_uninterrupted_one(tmp_path):
    """A stop between a run's last write and its instance table (on workers the clouds
    are written well before the main process assembles the run) leaves every cloud and
    no table: the resumed run keeps every frame and must still list their objects, from
    the kept sidecars, as the uninterrupted run does (it wrote an empty table)."""
    scene = street()
    whole, stopped = tmp_path / "whole", tmp_path / "stopped"
    run_of(scene, [job("pole", whole)], [1, 2], whole).run()
    run_of(scene, [job("pole", stopped)], [1, 2], stopped).run()
    (stopped / "fake_instances.json").unlink()  # what the stop left: clouds, no table
    again = run_of(scene, [job("pole", stopped)], [1, 2], stopped,
                   writer_kw={"resume": True}).run()
    assert (again.resumed, again.scanned) == (2, 0)
    table = (stopped / "fake_instances.json").read_text()
    assert table == (whole / "fake_instances.json").read_text()
    assert {v["object"] for v in json.loads(table)["instances"].values()} == {"ground", "wall",
                                                                             "car"}


def test_background_writes_give_the_same_files_and_end_with_the_run(tmp_path):
    """A writer in the background (rls scan) writes each scan's files while the next
    scan runs: the same bytes as writing in place, all complete when the run ends (a
    cancelled run and a piece too), and a failed write fails the run."""
    import pickle

    scene = street()
    for background in (False, True):
        out = tmp_path / str(background)
        jobs = [job("pole", out), job("mast", out)]
        run_of(scene, jobs, [1, 2, 3], out, writer_kw={"background": background}).run()
        cut = out / "cut"
        run_of(scene, [job("pole", cut)], [1, 2, 3], cut, writer_kw={"background": background},
               cancelled=lambda: scene.frame == 3).run()
        assert len(list(cut.glob("*.json"))) == 2
    for a in (tmp_path / "False").rglob("*.*"):
        b = tmp_path / "True" / a.relative_to(tmp_path / "False")
        assert a.read_bytes() == b.read_bytes(), a.name
    writer = CloudWriter(scene.name, background=True)
    assert pickle.loads(pickle.dumps(writer)).background  # sent to workers
    blocked = tmp_path / "blocked"
    blocked.mkdir()
    run = run_of(scene, [job("pole", blocked)], [1, 2], blocked,
                 writer_kw={"background": True})
    (blocked / "fake_pole_000002.pcd").mkdir()  # in the way of the second cloud
    with pytest.raises(OutputError, match="directory"):
        run.run()


def test_bad_input_fails_before_anything_is_scanned(tmp_path):
    scene = street()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OutputError, match="cannot create output folder"):
        run_of(scene, [job("pole", blocker / "out")], [1], tmp_path)
    with pytest.raises(SceneError, match="no LiDAR objects"):
        run_of(scene, [], [1])
    with pytest.raises(SceneError, match="no frames"):
        run_of(scene, [job("pole")], [])
    bad_template = SensorJob("pole", job("pole", tmp_path).settings.override(
        template="{camera}"), PRESET)
    with pytest.raises(OutputError, match="unknown placeholder"):
        run_of(scene, [bad_template], [1], tmp_path)
    assert scene.calls["read"] == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_settings_choices_are_checked_with_the_valid_values_named():
    with pytest.raises(SettingsError, match="unknown motion mode 'fast'; choose one of "
                                            "exact, substeps, snapshot"):
        ScanSettings(motion="fast")
    with pytest.raises(SettingsError, match="unknown ray-casting backend 'optix'"):
        LidarSettings(backend="optix")
    with pytest.raises(SettingsError, match="unknown cloud format 'e57'"):
        OutputSettings(format="e57")
    with pytest.raises(SettingsError, match="unknown point type 'kitti'; choose one of rls, "
                                            "velodyne, ouster, hesai, autoware"):
        OutputSettings(point_type="kitti")
    with pytest.raises(SettingsError, match="unknown coordinate frame"):
        ScanSettings(frame_space="camera")
    with pytest.raises(SettingsError, match="sub-steps"):
        ScanSettings(substeps=-1)
    with pytest.raises(SettingsError, match="unknown setting"):
        LidarSettings().override(colour="red")
    from rls_addon.core.casting import caster_factory

    with pytest.raises(SettingsError, match="choose one of auto, bvhtree, embree"):
        caster_factory("optix")


def test_overrides_change_only_the_fields_given():
    base = LidarSettings(preset="velodyne_vlp16",
                         scan=ScanSettings(seed=4, motion="snapshot"),
                         output=OutputSettings(format="ply_binary", fields=("x", "y", "z", "range")))
    got = base.override(seed=None, format=None, motion="exact", template="{frame}")
    assert got.scan.seed == 4 and got.output.format == "ply_binary"
    assert got.scan.motion == "exact" and got.output.template == "{frame}"
    assert got.output.fields == ("x", "y", "z", "range") and got.preset == "velodyne_vlp16"
    assert OutputSettings(fields=("ring", "x", "y", "z", "range")).fields == \
        ("x", "y", "z", "range", "ring")  # always the files' own order


def test_a_stopped_run_counts_the_scans_its_workers_wrote(tmp_path):
    """Issue 31: Ctrl-C of a Dask run said 'after 0 of 2000 scans' with 382 frames on
    disk: the coordinator counts only the pieces it heard back from. It now counts the
    scans whose files are complete."""
    scene = street()
    jobs = [job("pole", tmp_path), job("mast", tmp_path)]
    run_of(scene, jobs, [1, 2, 3], tmp_path).run()  # what the workers finished
    whole = run_of(scene, jobs, [1, 2, 3, 4, 5, 6], tmp_path, writer_kw={"resume": True})
    assert whole.index == 0 and whole.complete_on_disk() == 6
    (tmp_path / "fake_mast_000002.json").unlink()  # a cloud whose sidecar never came
    assert whole.complete_on_disk() == 5

    from rls_addon.commands.scan import interrupted_at

    assert interrupted_at(whole) == " after 5 of 12 scans"
    assert interrupted_at(None) == ""


def test_a_stopped_bag_run_does_not_promise_a_resume(tmp_path):
    """Ctrl-C of 'rls scan --format mcap' said 'finished files are complete ...; rerun
    with --resume to continue' with no file left, and --resume is refused for a bag."""
    from types import SimpleNamespace

    from rls_addon.commands.scan import interrupted_message
    from rls_addon.core.output.io.bag_writer import BagWriter

    bag = SimpleNamespace(writer=BagWriter("scene", str(tmp_path)), index=37, total=60,
                          finished=False, complete_on_disk=lambda: 0)
    line = interrupted_message(bag)
    assert line.startswith("rls: interrupted after 37 of 60 scans; a ROS 2 bag")
    assert "--resume to continue" not in line and "none was left" in line
    from rls_addon.core.output.io.writer import CloudWriter

    files = SimpleNamespace(writer=CloudWriter("scene"), index=3, total=9, finished=True)
    assert interrupted_message(files).endswith(
        "rerun with --resume to continue (the run's table of objects "
        "(<scene>_instances.json) is written once every scan is done)")
    # a scan that writes nothing (no writer) has no run-level files to speak of
    nothing = SimpleNamespace(writer=None, index=3, total=9)
    assert interrupted_message(nothing).endswith("rerun with --resume to continue")


def test_a_run_whose_files_will_not_fit_stops_after_its_first_scan(tmp_path, monkeypatch):
    """Issue 31: a run of 1,000,000 frames wrote 42 GB before anything said it needed
    about 2.5 TB. Each sensor's first scan gives its bytes per scan; what is still to
    come must fit in the free space."""
    from rls_addon.core.scan import disk_budget

    scene = street()
    first = run_of(scene, [job("pole", tmp_path)], [1], tmp_path).run()
    per_scan = sum(p.stat().st_size for p in tmp_path.glob("fake_pole_000001.*"))
    for p in tmp_path.iterdir():
        p.unlink()
    free = {"bytes": int(per_scan * 5.5)}  # room for 5 more scans, not 9
    real = disk_budget.DiskBudget.__init__
    monkeypatch.setattr(disk_budget.DiskBudget, "__init__", lambda self, remaining, free_=None:
                        real(self, remaining, lambda folder: free["bytes"]))
    with pytest.raises(OutputError, match=r"pole's first scan wrote .* its 9 scans still "
                                          r"to come need about .* are free in"):
        run_of(scene, [job("pole", tmp_path)], list(range(1, 11)), tmp_path).run()
    assert sorted(p.name for p in tmp_path.glob("fake_pole_*")) == [
        "fake_pole_000001.json", "fake_pole_000001.pcd"]  # the one scan, complete
    # resumed, only the scans still missing count: after the first of the 9, 8 to come fit
    free["bytes"] = int(per_scan * 9.5)
    run_of(scene, [job("pole", tmp_path)], list(range(1, 11)), tmp_path,
           writer_kw={"resume": True}).run()
    assert len(list(tmp_path.glob("fake_pole_*.pcd"))) == 10
    assert first.scanned == 1


def test_the_disk_budget_waits_for_files_written_behind_the_scan(tmp_path, monkeypatch):
    """rls scan writes each scan's files on a background thread: the budget measures a
    sensor's first scan once its files are on disk, a scan or two later."""
    from rls_addon.core.output.io.writer import WRITES_BEHIND
    from rls_addon.core.scan import disk_budget

    scene = street()
    run_of(scene, [job("pole", tmp_path)], [1], tmp_path).run()
    per_scan = sum(p.stat().st_size for p in tmp_path.glob("fake_pole_000001.*"))
    for p in tmp_path.iterdir():
        p.unlink()
    real = disk_budget.DiskBudget.__init__
    monkeypatch.setattr(disk_budget.DiskBudget, "__init__", lambda self, remaining, free_=None:
                        real(self, remaining, lambda folder: int(per_scan * 5.5)))
    with pytest.raises(OutputError, match="will not fit"):
        run_of(scene, [job("pole", tmp_path)], list(range(1, 31)), tmp_path,
               writer_kw={"background": True}).run()
    written = sorted(p.name for p in tmp_path.glob("fake_pole_*.pcd"))
    assert 1 <= len(written) <= WRITES_BEHIND + 2, written  # stopped near the start
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    for name in written:  # each complete, with its sidecar
        assert (tmp_path / name.replace(".pcd", ".json")).is_file()


def test_moving_bodies_are_built_once_while_their_meshes_are_the_same(monkeypatch):
    """A car driving past a still sensor: its body (its triangles in its own frame) is
    built for the first frame and kept, with each frame's track, while the scene reads
    the same mesh (its id); its geometry is not digested for that."""
    from rls_addon.core.scene import geometry

    digests = []
    real = geometry.SceneGeometry.fingerprint
    monkeypatch.setattr(geometry.SceneGeometry, "fingerprint",
                        lambda self: digests.append(1) or real(self))
    run = run_of(street(car_speed=12.0), [job("pole")], [1, 2, 3, 4]).run()
    assert run.structure_builds == 2 and not digests  # the static scene and the car


def test_a_steps_wall_time_and_its_parts(tmp_path):
    """The progress line once gave only the scan's own seconds (0.06 s of a 0.28 s
    frame): a step also says its wall time and what it went on. A frame change made to
    take at least 50 ms shows there, in the wall time and not in the scan's."""
    import time

    from rls_addon.core.scan.run import STEP_PARTS

    scene = street()
    slow_set = scene.set_frame

    def set_frame(frame):
        time.sleep(0.05)
        slow_set(frame)

    scene.set_frame = set_frame
    steps = []
    run_of(scene, [job("pole", tmp_path)], [2, 3], tmp_path, progress=steps.append).run()
    for s in steps:
        assert tuple(s.parts) == STEP_PARTS
        assert s.parts["frame"] >= 0.05 and s.parts["scan"] == s.seconds
        assert sum(s.parts.values()) == pytest.approx(s.wall_s, abs=1e-9)
        assert s.wall_s >= s.seconds + 0.05


def test_world_frame_points_far_from_the_origin_are_warned_of(tmp_path):
    """A study audit found world-frame clouds at a map's UTM coordinates (5e5, 4.2e6 m)
    rounded to 0.5 m by the files' float32 x, y, z (rls metrics then counted 3820
    points in a region that holds 3799), with no word. The run says so, in the
    sidecar too; the same street near the origin, the sensor frame and LAS say
    nothing."""
    from rls_addon.core.output.io.fields import float32_warning

    from .fakes import FakeScene, translation

    far = np.array([5e5, 4.2e6, 0.0])
    boxes = {"ground": (tuple(far + (-40, -40, -1.2)), tuple(far + (40, 40, -1.0)), 1),
             "wall": (tuple(far + (10, -15, -1.0)), tuple(far + (11, 15, 4.0)), 4)}
    scene = FakeScene(boxes, {"pole": lambda s: translation(tuple(far + (0.0, 0.0, 0.5)))}, {})
    run = run_of(scene, [job("pole", tmp_path, frame_space="world")], [1], tmp_path).run()
    (warning,) = [w for w in run.warnings if "world-frame points reach" in w]
    assert "step by 500 mm" in warning and "as LAS" in warning
    side = read_sidecar(tmp_path / "fake_pole_000001.pcd")
    assert any("world-frame points reach 4,200" in w for w in side["warnings"])
    near = run_of(street(), [job("pole", tmp_path / "near", frame_space="world")], [1],
                  tmp_path / "near").run()
    assert not [w for w in near.warnings if "world-frame" in w]
    sensor = run_of(scene, [job("pole", tmp_path / "s")], [1], tmp_path / "s").run()
    assert not [w for w in sensor.warnings if "world-frame" in w]
    pts = np.zeros(3, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    pts["y"] = 4.2e6
    assert float32_warning(pts, "las") is None and float32_warning(pts, "ply_binary")
    pts["y"] = 16000.0
    assert float32_warning(pts, "pcd_binary") is None
