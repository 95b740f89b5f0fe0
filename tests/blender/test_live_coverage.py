"""Live coverage in the ``bpy`` module: a LiDAR moved, turned, retargeted, given another
preset and another frame, step by step with Live on; after each step its preview, the
panel's InfraD / InfraNUC and the coverage map equal a fresh scan's. Handlers run on
``view_layer.update()`` and ``frame_set``; timers never fire here, so the test calls
``live.tick`` when it asks to be called, as Blender's timer would."""

import time

import numpy as np
import pytest

from .conftest import bpy, mesh_object
from .ops_helpers import add_lidar_op, labelled_ground


def drive(live):
    """Call the timer's callback as ``bpy.app.timers`` would, until it is idle."""
    assert bpy.app.timers.is_registered(live.tick)  # the handler asked for it
    for _ in range(200):
        wait = live.tick()
        if wait is None:
            return
        time.sleep(wait)
    raise AssertionError("live coverage never settled")


def fresh(obj):
    """A fresh scan of LiDAR ``obj`` as Scan Frame makes it, in world coordinates."""
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.sensor import read_settings

    settings = read_settings(obj).override(frame_space="world")
    return scan_lidar(obj, settings=settings)[0].points


def preview_xyz(obj):
    from rls_addon.blender.preview import preview_object, preview_world_points

    return preview_world_points(preview_object(obj))[0]


def check_follows(sc, lidars):
    """The previews, the panel's numbers and the map are a fresh scan's."""
    from rls_addon.blender.coverage_map import map_bands, map_colours
    from rls_addon.blender.region import lob_polygon_world
    from rls_addon.core.live.coverage import cells, level_colours, levels
    from rls_addon.core.metrics.infra import infra_lob_metrics

    from rls_addon.blender import live

    clouds = [fresh(o) for o in lidars]
    for obj, pts in zip(lidars, clouds):
        assert live.session().clouds[obj.name].tobytes() == pts.tobytes()  # byte for byte
        got = preview_xyz(obj)
        want = np.stack([pts["x"], pts["y"], pts["z"]], 1).astype(np.float32)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)  # the same points, to the bit
    rs, p = sc.rls, sc.rls_live
    ref = infra_lob_metrics(clouds, lob_polygon_world(bpy.data.objects["InfraLOB"]),
                            labels=rs.metric_labels, disks=rs.metric_disks, radius=0.7,
                            seed=rs.metric_seed, cell=2.0)
    assert p.points == ref.n_points
    assert p.infra_d == pytest.approx(ref.infra_d, rel=1e-6)  # a float property: 32 bits
    assert p.infra_nuc == pytest.approx(ref.infra_nuc, rel=1e-6)
    assert p.sensors == ", ".join(o.name for o in lidars)
    shown = map_colours(bpy.data.objects["RLS coverage InfraLOB"])
    want = cells(ref.density)[1]
    np.testing.assert_allclose(shown, want, atol=1 / 255 + 1e-6)
    # Solid shading's default (Color: Material): each cell's band, in its colour
    band, colours = map_bands(bpy.data.objects["RLS coverage InfraLOB"])
    np.testing.assert_array_equal(band, levels(ref.density))
    np.testing.assert_allclose(colours, level_colours(), atol=1e-4)
    return ref


@pytest.fixture
def live_scene(scene):
    from rls_addon.blender import live

    labelled_ground(40.0)
    mesh_object("Kiosk", [(2, 2, 0), (5, 2, 0), (5, 5, 0), (2, 5, 0), (2, 2, 3), (5, 2, 3),
                          (5, 5, 3), (2, 5, 3)],
                [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                 (3, 0, 4, 7)])
    scene.cursor.location = (0.0, 0.0, 0.0)
    bpy.ops.object.rls_add_infralob(size_x=24.0, size_y=24.0)
    rs = scene.rls
    rs.metric_disks, rs.metric_cell = 800, 2.0
    a = add_lidar_op(location=(-9.0, -9.0, 4.0))
    b = add_lidar_op(location=(9.0, -9.0, 4.0))
    scene.rls_live.debounce_ms = 20.0
    yield scene, live, a, b
    live.stop()


def test_live_coverage_follows_each_step_of_a_lidar(live_scene):
    sc, live, a, b = live_scene
    moving_car()  # (exact motion through it: every rescan below reuses its samples)
    bpy.context.view_layer.objects.active = bpy.data.objects["InfraLOB"]
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    assert sc.rls_live.active and sc.rls_live.scans == 2  # both scanned once
    kept = live.session().sweeps
    misses = kept.misses
    check_follows(sc, [a, b])
    scans = sc.rls_live.scans
    target = bpy.data.objects.new("Target", None)
    sc.collection.objects.link(target)
    target.location = (0.0, 0.0, 0.0)

    def moved_a():
        a.location = (-6.0, -8.0, 4.5)

    def turned_a():
        a.rotation_euler = (0.0, 0.3, 0.8)

    def retargeted_a():  # a Track To constraint on A, then its target moved
        con = a.constraints.new("TRACK_TO")
        con.target, con.track_axis, con.up_axis = target, "TRACK_X", "UP_Z"
        bpy.context.view_layer.update()
        live.tick()  # (noted, still for less than the debounce: nothing yet)
        target.location = (4.0, 6.0, 0.0)

    def preset_of_a():
        a.rls_lidar.preset_id = "velodyne_vlp16"

    for step in (moved_a, turned_a, retargeted_a, preset_of_a):
        before = np.array(preview_xyz(a))
        step()
        bpy.context.view_layer.update()  # the depsgraph handler notes it
        assert sc.rls_live.scans == scans  # no work in the handler
        drive(live)
        scans += 1
        assert sc.rls_live.scans == scans, step.__name__  # A alone, once
        assert preview_xyz(a).shape != before.shape or not np.allclose(preview_xyz(a), before)
        check_follows(sc, [a, b])
        # RLS's own preview and map updates feed back into the handler: ignored
        bpy.context.view_layer.update()
        assert not live.session().scheduler.busy
    assert sc.rls_live.latency_ms > 0 and "live: 2 LiDAR(s) over InfraLOB" in sc.rls_live.status
    # the car sampled by the first scans only (the VLP-16 sweeps in the same 0.1 s)
    assert kept.misses == misses and kept.reused > 0


def test_another_frame_rescans_an_animated_lidar(live_scene):
    sc, live, a, b = live_scene
    a.keyframe_insert("location", frame=1)
    a.location = (-3.0, 0.0, 4.0)
    a.keyframe_insert("location", frame=11)
    sc.frame_set(1)
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    scans = sc.rls_live.scans
    sc.frame_set(6)  # the frame handler notes both LiDARs (the frame is theirs too)
    drive(live)
    assert sc.rls_live.scans == scans + 2
    assert tuple(a.location) == pytest.approx((-6.0, -4.5, 4.0))
    check_follows(sc, [a, b])


def test_a_lidar_removed_leaves_the_count(live_scene):
    sc, live, a, b = live_scene
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    bpy.data.objects.remove(b)
    bpy.context.view_layer.update()
    assert sc.rls_live.sensors == a.name
    check_follows(sc, [a])


def test_a_scene_over_budget_falls_back_to_on_demand(live_scene):
    sc, live, a, b = live_scene
    sc.rls_live.budget_ms = 1.0  # less than any scan: every update is over
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    for x in (-8.0, -7.0):  # two updates over budget (the first one is not judged)
        a.location.x = x
        bpy.context.view_layer.update()
        drive(live)
    assert "over the 1 ms budget" in sc.rls_live.status
    assert "updated on demand" in sc.rls_live.status and sc.rls_live.on_demand
    from types import SimpleNamespace

    from rls_addon import ui

    from .test_ui_panels import _draw

    lob = bpy.data.objects["InfraLOB"]
    log = _draw(ui.OBJECT_PT_rls_live, SimpleNamespace(object=lob, active_object=lob, scene=sc))
    assert [kw for n, a_, kw in log if n == "operator" and a_ == ("rls.live_update",)] == [
        {"text": "Update Coverage", "icon": "FILE_REFRESH"}]  # said, and the button named
    assert ("label", {"text": sc.rls_live.status, "icon": "ERROR"}) in [
        (n, kw) for n, _, kw in log]
    scans = sc.rls_live.scans
    a.location.x = -6.0
    bpy.context.view_layer.update()
    time.sleep(0.03)
    assert live.tick() is None and sc.rls_live.scans == scans  # nothing by itself
    assert bpy.ops.rls.live_update() == {"FINISHED"}  # the panel's Update button
    assert sc.rls_live.scans == scans + 1 and not sc.rls_live.on_demand  # live again
    check_follows(sc, [a, b])


def test_live_off_removes_handlers_timer_and_map(live_scene):
    sc, live, a, b = live_scene
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    assert "RLS coverage InfraLOB" in bpy.data.objects
    a.location.x = -5.0
    bpy.context.view_layer.update()
    assert bpy.app.timers.is_registered(live.tick)
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}  # the toggle: off
    assert not sc.rls_live.active and not bpy.app.timers.is_registered(live.tick)
    assert live.session() is None and not live_handlers(live)
    assert "RLS coverage InfraLOB" not in bpy.data.objects
    assert "LiDAR points" in bpy.data.objects  # the previews stay: the last scans


def live_handlers(live):
    """Live coverage's functions still in any of Blender's handler lists."""
    fns = {live.on_edit, live.on_change, live.on_undo, live.on_load}
    h = bpy.app.handlers
    return [(name, fn.__name__) for name in ("depsgraph_update_post", "frame_change_post",
                                             "undo_post", "redo_post", "load_pre")
            for fn in getattr(h, name) if fn in fns]


def test_another_file_ends_live_coverage(live_scene, tmp_path):
    sc, live, a, b = live_scene
    path = str(tmp_path / "other.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    a.location.x = -5.0
    bpy.context.view_layer.update()  # a rescan waiting for the timer
    assert bpy.app.timers.is_registered(live.tick)
    bpy.ops.wm.open_mainfile(filepath=path)  # (RLS stays registered: load_pre ends it)
    assert hasattr(bpy.types.Object, "rls_lidar")
    assert live.session() is None and not bpy.app.timers.is_registered(live.tick)
    assert live_handlers(live) in ([], [("load_pre", "on_load")])  # (idle till the next start)


def test_live_needs_a_region_and_a_lidar(scene):
    with pytest.raises(RuntimeError, match="Select an InfraLOB region"):
        bpy.ops.rls.live_coverage()
    bpy.ops.object.rls_add_infralob()
    with pytest.raises(RuntimeError, match="The scene has no LiDAR objects"):
        bpy.ops.rls.live_coverage()
    with pytest.raises(RuntimeError, match="Turn Live Coverage on first"):
        bpy.ops.rls.live_update()


def test_live_panels_draw_the_stored_numbers_only(live_scene, monkeypatch):
    from types import SimpleNamespace

    from rls_addon import ui
    from rls_addon.core.live.schedule import LiveScheduler

    from .test_ui_panels import _draw, _explode

    sc, live, a, b = live_scene
    lob = bpy.data.objects["InfraLOB"]
    off = _draw(ui.OBJECT_PT_rls_live, SimpleNamespace(object=lob, active_object=lob, scene=sc))
    assert [a_ for n, a_, _ in off if n == "operator"] == [("rls.live_coverage",)]
    bpy.context.view_layer.objects.active = lob
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    monkeypatch.setattr(LiveScheduler, "tick", _explode)  # drawing does no live work
    monkeypatch.setattr(LiveScheduler, "update_now", _explode)
    for cls, obj in ((ui.OBJECT_PT_rls_live, lob), (ui.OBJECT_PT_rls_lidar_live, a)):
        log = _draw(cls, SimpleNamespace(object=obj, active_object=obj, scene=sc))
        ops = [a_[0] for n, a_, _ in log if n == "operator"]
        assert ops == ["rls.live_coverage", "rls.live_update"]
        labels = [kw.get("text", "") for n, _, kw in log if n == "label"]
        assert f"{sc.rls_live.infra_d:.3f} pts/m²" in labels
        assert f"{sc.rls_live.infra_nuc:.4f}" in labels
        assert any(t.startswith("Map: 0 (purple) to ") for t in labels)


def test_undo_of_a_move_is_followed(live_scene):
    sc, live, a, b = live_scene
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    first = (sc.rls_live.infra_d, sc.rls_live.points)
    bpy.ops.ed.undo_push(message="before the move")
    a.location.x = -3.0
    bpy.context.view_layer.update()
    bpy.ops.ed.undo_push(message="moved")
    drive(live)
    assert sc.rls_live.points != first[1]
    assert bpy.ops.ed.undo() == {"FINISHED"}  # the scene is reloaded: names, not pointers
    sc = bpy.context.scene
    drive(live)
    a, b = bpy.data.objects["LiDAR"], bpy.data.objects["LiDAR.001"]
    assert tuple(a.location) == pytest.approx((-9.0, -9.0, 4.0))
    assert (sc.rls_live.infra_d, sc.rls_live.points) == pytest.approx(first)
    check_follows(sc, [a, b])


def moving_car(frames=(1, 21)):
    """A car driving across in front of both LiDARs (keyed at ``frames``), labelled a
    vehicle: what a LiDAR's exact motion samples over each sweep."""
    from rls_addon.blender.scenes.build import action_curves

    car = mesh_object("Car", [(-2.2, -0.9, 0), (2.2, -0.9, 0), (2.2, 0.9, 0), (-2.2, 0.9, 0),
                              (-2.2, -0.9, 1.5), (2.2, -0.9, 1.5), (2.2, 0.9, 1.5),
                              (-2.2, 0.9, 1.5)],
                      [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                       (3, 0, 4, 7)])
    car["rls_label"] = "vehicle"
    car.location = (-8.0, 0.0, 0.0)
    car.keyframe_insert("location", frame=frames[0])
    car.location = (8.0, 0.0, 0.0)
    car.keyframe_insert("location", frame=frames[1])
    for fc in action_curves(car.animation_data.action):
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"
    bpy.context.scene.frame_set(frames[0] + 4)
    return car


def test_a_still_lidars_rescans_reuse_the_traffics_samples_until_another_object_changes(
        live_scene):
    from rls_addon.blender.scenes.build import action_curves

    sc, live, a, b = live_scene
    car = moving_car()
    assert a.rls_lidar.motion == "exact"
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    kept = live.session().sweeps
    assert kept.misses > 0 and len(kept) > 0  # the first scans sampled the car's sweep
    misses = kept.misses
    for x in (-7.0, -6.0):  # moved: the car is not sampled again, and a fresh scan's
        a.location.x = x
        bpy.context.view_layer.update()
        drive(live)
        assert kept.misses == misses and kept.reused > 0
        check_follows(sc, [a, b])
    # the car's animation edited (a key moved): the kept samples are forgotten, and
    # both LiDARs are rescanned with the car sampled anew, as a fresh scan does
    (fx,) = [fc for fc in action_curves(car.animation_data.action)
             if fc.data_path == "location" and fc.array_index == 0]
    fx.keyframe_points[1].co.y = 2.0
    fx.update()
    scans = sc.rls_live.scans
    bpy.context.view_layer.update()
    assert len(kept) == 0
    drive(live)
    assert kept.misses > misses and sc.rls_live.scans == scans + 2
    check_follows(sc, [a, b])
    # another object moved (not animated: the kiosk): the same
    misses = kept.misses
    bpy.data.objects["Kiosk"].location.x += 1.0
    bpy.context.view_layer.update()
    assert len(kept) == 0
    a.location.x = -4.0  # (and a LiDAR moved meanwhile)
    bpy.context.view_layer.update()
    drive(live)
    assert kept.misses > misses and sc.rls_live.scans == scans + 4
    check_follows(sc, [a, b])


def test_another_frame_or_frame_rate_samples_the_sweep_anew(live_scene):
    sc, live, a, b = live_scene
    moving_car()
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    kept = live.session().sweeps
    misses = kept.misses
    sc.frame_set(sc.frame_current + 1)  # both LiDARs rescanned at the new frame
    drive(live)
    assert kept.misses > misses
    check_follows(sc, [a, b])
    misses = kept.misses
    sc.render.fps = 30  # the sweep's sub-frames fall elsewhere
    bpy.context.view_layer.update()
    assert len(kept) == 0
    drive(live)
    assert kept.misses > misses
    check_follows(sc, [a, b])


def test_a_newer_move_supersedes_a_rescan_not_shown_yet(live_scene):
    sc, live, a, b = live_scene
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    scans = sc.rls_live.scans
    a.location.x = -7.0
    bpy.context.view_layer.update()
    time.sleep(sc.rls_live.debounce_ms / 1000.0)
    assert live.tick() == 0.0 and sc.rls_live.scans == scans + 1  # scanned, not shown
    a.location.x = -6.0  # moved again before the timer shows it: that scan is dropped
    bpy.context.view_layer.update()
    drive(live)
    assert sc.rls_live.scans == scans + 2 and sc.rls_live.superseded == 1
    check_follows(sc, [a, b])  # the newer pose's


def test_a_drag_of_20_steps_costs_one_scan(live_scene):
    """A drag at 60 Hz with Blender's timer called in between (a clock of the test's
    own: the machine's load cannot make a step late)."""
    sc, live, a, b = live_scene
    clock = [0.0]
    session = live.start(sc, bpy.data.objects["InfraLOB"], 40.0, 150.0,
                         clock=lambda: clock[0])
    scans = session.scheduler.scans
    for i in range(20):
        a.location.y += 0.1
        bpy.context.view_layer.update()
        end = clock[0] + 1 / 60
        while True:  # the timer between steps: asked to wait for the LiDAR to be still
            wait = live.tick()
            assert wait is not None and wait > 0
            if clock[0] + wait >= end:
                break
            clock[0] += wait
        clock[0] = end
    assert session.scheduler.scans == scans  # nothing while it moves
    while (wait := live.tick()) is not None:
        clock[0] += wait
    assert session.scheduler.scans == scans + 1 and session.scheduler.superseded == 0
    check_follows(sc, [a, b])


def test_update_coverage_rescans_every_lidar_after_an_edit_live_does_not_follow(live_scene):
    sc, live, a, b = live_scene
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    scans = sc.rls_live.scans
    bpy.data.objects["Kiosk"].hide_render = True  # a visibility: not followed by itself
    bpy.context.view_layer.update()
    assert not live.session().scheduler.busy
    assert bpy.ops.rls.live_update() == {"FINISHED"}  # the panel's Update button
    assert sc.rls_live.scans == scans + 2
    check_follows(sc, [a, b])
