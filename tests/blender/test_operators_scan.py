"""Scan operators in background mode (no window), as batch scripts call them:
scan frame, scan all LiDARs, scan a frame range (run through, cancelled), bad input."""

import json


import numpy as np
import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground, user_dir  # noqa: F401 (fixture)


def _files(d):
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


def test_add_lidar_places_it_at_the_cursor_with_a_fov_wire(scene):
    obj = add_lidar_op("velodyne_vlp16", location=(1.0, 2.0, 3.0))
    assert obj.rls_lidar.is_lidar and obj.rls_lidar.preset == "velodyne_vlp16"
    assert tuple(obj.location) == (1.0, 2.0, 3.0)
    fov = [c for c in obj.children if c.get("rls_fov")]
    assert len(fov) == 1
    fov = fov[0]
    assert fov.type == "MESH" and fov.display_type == "WIRE" and fov.hide_render
    assert len(fov.data.polygons) == 0 and len(fov.data.edges) > 0
    co = np.array([v.co for v in fov.data.vertices])
    r = np.linalg.norm(co, axis=1)
    far = co[r > 1e-6]
    np.testing.assert_allclose(np.linalg.norm(far, axis=1), obj.rls_lidar.fov_length, rtol=1e-5)
    el = np.degrees(np.arcsin(far[:, 2] / np.linalg.norm(far, axis=1)))
    assert el.min() == pytest.approx(-15.0, abs=0.01) and el.max() == pytest.approx(15.0, abs=0.01)


def test_fov_follows_the_preset_and_can_be_hidden(scene):
    obj = add_lidar_op("velodyne_vlp16")
    obj.rls_lidar.preset = "livox_mid40"  # a 38.4 degree cone looking along +X
    fov = next(c for c in obj.children if c.get("rls_fov"))
    assert fov["rls_fov_preset"] == "livox_mid40"
    co = np.array([v.co for v in fov.data.vertices])
    far = co[np.linalg.norm(co, axis=1) > 1e-6]
    off_axis = np.degrees(np.arccos(far[:, 0] / np.linalg.norm(far, axis=1)))
    assert off_axis.max() == pytest.approx(19.2, abs=0.6)  # half of the 38.4 degree FOV
    obj.rls_lidar.fov_length = 7.0
    co = np.array([v.co for v in fov.data.vertices])
    assert np.linalg.norm(co, axis=1).max() == pytest.approx(7.0, rel=1e-5)
    obj.rls_lidar.show_fov = False
    assert not [c for c in obj.children if c.get("rls_fov")]
    assert "LiDAR FOV" not in bpy.data.objects


def test_fov_wire_is_not_scanned(scene, tmp_path):
    labelled_ground()
    obj = add_lidar_op(out=tmp_path)
    obj.rls_lidar.fov_length = 1.0  # the wire around the sensor must not block rays
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    from rls_addon.operators import LAST_RUN

    assert LAST_RUN["points"] > 1000


def test_scan_frame_writes_only_the_chosen_fields_and_colours_the_preview(scene, tmp_path):
    from rls_addon.core.output.io import read_records, read_sidecar

    labelled_ground()
    add_lidar_op(out=tmp_path, file_format="ply_binary", fields={"intensity", "label"},
             frame_space="world", preview_color="ring")
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    files = _files(tmp_path)
    assert files == ["Scene_LiDAR_000001.json", "Scene_LiDAR_000001.ply", "Scene_instances.json"]
    rec = read_records(tmp_path / files[1])
    assert rec.dtype.names == ("x", "y", "z", "intensity", "label")
    assert set(np.unique(rec["label"])) == {1}
    side = read_sidecar(tmp_path / files[1])
    assert side["fields"] == ["x", "y", "z", "intensity", "label"] and side["frame_space"] == "world"
    preview = bpy.data.objects["LiDAR points"]
    assert len(preview.data.vertices) == len(rec)
    assert preview["rls_color_by"] == "ring"
    mod = preview.modifiers["RLS Points"]
    assert mod.type == "NODES" and mod.node_group.name == "RLS Points"


def test_scan_settings_are_mapped_in_one_place(scene):
    from rls_addon.blender.sensor import read_settings, sensor_job

    obj = add_lidar_op("velodyne_vlp16")
    s = obj.rls_lidar
    s.seed, s.frame_space, s.noise, s.dropout = 7, "world", True, False
    s.use_min_range, s.min_range = True, 1.5
    s.use_max_range, s.max_range = True, 42.0
    s.use_noise_sigma, s.noise_sigma = True, 0.05
    s.motion, s.substeps, s.ghosting = "substeps", 6, False
    job = sensor_job(obj)
    preset, st = job.preset, job.settings.scan
    assert preset.id == "velodyne_vlp16"
    assert (st.seed, st.frame_space, st.noise, st.dropout) == (7, "world", True, False)
    assert (st.min_range_m, st.max_range_m) == (1.5, 42.0)
    assert st.noise_sigma_m == pytest.approx(0.05)
    assert (st.motion, st.substeps, st.ghosting) == ("substeps", 6, False)
    s.use_min_range = s.use_max_range = s.use_noise_sigma = False
    st = read_settings(obj).scan
    assert st.min_range_m is None and st.max_range_m is None and st.noise_sigma_m is None


def test_weather_and_detection_are_mapped_from_the_panel(scene):
    from rls_addon.blender.sensor import read_settings

    obj = add_lidar_op("livox_mid40")
    s = obj.rls_lidar
    st = read_settings(obj).scan
    assert st.weather is None and st.detection == "auto"
    s.weather, s.fog_visibility, s.detection = "fog", 50.0, "carla"
    st = read_settings(obj).scan
    assert st.weather == "fog:visibility=50" and st.detection == "carla"
    s.weather, s.precipitation_rate = "rain", 12.5
    assert read_settings(obj).scan.weather == "rain:rate=12.5"
    s.weather, s.precipitation_rate, s.snow_type = "snow", 2.0, "wet"
    assert read_settings(obj).scan.weather == "snow:rate=2,type=wet"


def test_motion_mode_reaches_the_sidecar(scene, tmp_path):
    from rls_addon.core.output.io import read_sidecar

    labelled_ground()
    add_lidar_op(out=tmp_path, motion="snapshot", ghosting=False)
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    side = read_sidecar(next(tmp_path.glob("*.pcd")))
    assert side["effects"]["motion"] == "snapshot" and side["effects"]["ghosting"] is False


def test_scan_all_lidars(scene, tmp_path):
    labelled_ground()
    add_lidar_op(out=tmp_path, location=(0, 0, 2))
    add_lidar_op(out=tmp_path, location=(5, 0, 2))
    bpy.context.view_layer.objects.active = None
    assert bpy.ops.rls.scan_all() == {"FINISHED"}
    assert _files(tmp_path) == ["Scene_LiDAR.001_000001.json", "Scene_LiDAR.001_000001.pcd",
                                "Scene_LiDAR_000001.json", "Scene_LiDAR_000001.pcd",
                                "Scene_instances.json"]
    assert "LiDAR points" in bpy.data.objects and "LiDAR.001 points" in bpy.data.objects


def test_scan_range_runs_through_in_background(scene, tmp_path):
    from rls_addon.operators import LAST_RUN

    labelled_ground()
    scene.frame_start, scene.frame_end = 3, 6
    scene.frame_set(4)
    add_lidar_op(out=tmp_path)
    # INVOKE_DEFAULT as a UI button would: without a window it must run in execute()
    assert bpy.ops.rls.scan_range("INVOKE_DEFAULT") == {"FINISHED"}
    assert LAST_RUN["frames_done"] == [3, 4, 5, 6] and not LAST_RUN["cancelled"]
    assert len([f for f in _files(tmp_path) if f.endswith(".pcd")]) == 4
    assert scene.frame_current == 4  # the frame the user was on
    assert bpy.ops.rls.scan_range(use_scene_range=False, frame_start=10, frame_end=14,
                                  frame_step=2) == {"FINISHED"}
    assert LAST_RUN["frames_done"] == [10, 12, 14]


def test_scan_range_cancel_keeps_only_complete_frames(scene, tmp_path):
    from rls_addon.blender import batch
    from rls_addon.operators import LAST_RUN

    labelled_ground()
    scene.frame_start, scene.frame_end = 1, 6
    add_lidar_op(out=tmp_path)
    add_lidar_op(out=tmp_path, location=(3, 0, 2))

    def press_esc_at_frame_3(sc, *args):
        if sc.frame_current == 3:
            batch.request_cancel()

    bpy.app.handlers.frame_change_post.append(press_esc_at_frame_3)
    try:
        result = bpy.ops.rls.scan_range(all_lidars=True)
    finally:
        bpy.app.handlers.frame_change_post.remove(press_esc_at_frame_3)
    assert result == {"CANCELLED"}
    assert LAST_RUN["cancelled"] and LAST_RUN["frames_done"] == [1, 2]
    files = _files(tmp_path)
    assert len(files) == 2 * 2 * 2  # 2 frames x 2 LiDARs x (cloud + sidecar)
    assert not any("000003" in f for f in files)
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    for f in tmp_path.glob("*.json"):
        json.loads(f.read_text())  # every sidecar complete
    assert scene.frame_current == 1
    assert not batch.cancel_requested()  # the next job starts clean
    assert bpy.ops.rls.scan_range(all_lidars=True, overwrite=True) == {"FINISHED"}
    assert LAST_RUN["frames_done"] == [1, 2, 3, 4, 5, 6]


def test_no_lidar_selected_poll_says_why(scene):
    labelled_ground()
    with pytest.raises(RuntimeError, match="Select a LiDAR object"):
        bpy.ops.rls.scan_frame()
    with pytest.raises(RuntimeError, match="no LiDAR objects"):
        bpy.ops.rls.scan_all()
    with pytest.raises(RuntimeError, match="no LiDAR objects"):
        bpy.ops.rls.scan_range()
    add_lidar_op()
    bpy.context.view_layer.objects.active = bpy.data.objects["Ground"]
    with pytest.raises(RuntimeError, match="select a LiDAR object, or enable 'All LiDARs'"):
        bpy.ops.rls.scan_range()


def test_no_meshes_in_the_scene_is_a_warning_not_a_crash(scene, tmp_path):
    from rls_addon.operators import LAST_RUN

    add_lidar_op(out=tmp_path)
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    assert LAST_RUN["points"] == 0
    assert any("no geometry" in w for w in LAST_RUN["warnings"]), LAST_RUN["warnings"]


def test_unwritable_output_directory_fails_before_scanning(scene, tmp_path):
    labelled_ground()
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    add_lidar_op(out=blocker / "clouds")
    with pytest.raises(RuntimeError, match="cannot create output folder .*a_file/clouds"):
        bpy.ops.rls.scan_frame()
    with pytest.raises(RuntimeError, match="cannot create output folder"):
        bpy.ops.rls.scan_range(use_scene_range=False, frame_start=1, frame_end=3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
    assert "LiDAR points" not in bpy.data.objects  # nothing scanned


def test_blend_relative_output_needs_a_saved_file(scene):
    labelled_ground()
    add_lidar_op()  # default output '//lidar/'
    with pytest.raises(RuntimeError, match="not saved yet"):
        bpy.ops.rls.scan_frame()
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}


def test_bad_template_is_reported(scene, tmp_path):
    labelled_ground()
    add_lidar_op(out=tmp_path, name_template="{camera}_{frame}")
    with pytest.raises(RuntimeError, match="unknown placeholder"):
        bpy.ops.rls.scan_frame()


def test_noise_override_changes_the_points(scene, tmp_path):
    from rls_addon.operators import LAST_RUN

    labelled_ground()
    obj = add_lidar_op(out=tmp_path, noise=True, use_noise_sigma=True, noise_sigma=0.0,
                       frame_space="world")
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    z = np.array([v.co.z for v in bpy.data.objects["LiDAR points"].data.vertices])
    assert np.abs(z).max() < 1e-4  # sigma overridden to 0: exact ground
    obj.rls_lidar.noise_sigma = 0.05
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}
    z = np.array([v.co.z for v in bpy.data.objects["LiDAR points"].data.vertices])
    assert 0.005 < z.std() < 0.05 and LAST_RUN["points"] > 1000  # range noise, seen in z



def test_modal_path_progress_and_esc(scene, tmp_path):
    """The modal loop (what a UI click runs), driven with synthetic timer and Esc events."""
    from types import SimpleNamespace

    from rls_addon.blender import batch
    from rls_addon.operators import LAST_RUN, RLS_OT_scan_range as Op

    labelled_ground()
    scene.frame_start, scene.frame_end = 1, 5
    add_lidar_op(out=tmp_path)
    ctx = bpy.context
    reports = []
    fake = SimpleNamespace(_timer=None, report=lambda kind, msg: reports.append((kind, msg)))
    fake._end = lambda c: Op._end(fake, c)
    fake._report = lambda run: Op._report(fake, run)
    fake._status = lambda c, t: Op._status(fake, c, t)
    fake._job = batch.make_run(ctx, [bpy.context.active_object], [1, 2, 3, 4, 5])
    ctx.window_manager.progress_begin(0, fake._job.total)
    timer = SimpleNamespace(type="TIMER")
    assert Op.modal(fake, ctx, SimpleNamespace(type="MOUSEMOVE")) == {"PASS_THROUGH"}
    assert Op.modal(fake, ctx, timer) == {"RUNNING_MODAL"}
    assert Op.modal(fake, ctx, timer) == {"RUNNING_MODAL"}
    assert "2/5 done" in fake._job.status()
    assert Op.modal(fake, ctx, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    assert LAST_RUN["frames_done"] == [1, 2] and LAST_RUN["cancelled"]
    said = {(next(iter(k)), m) for k, m in reports}
    assert ("WARNING", "Scan cancelled: 2 of 5 frames completed, 2 files written") in said
    assert ("INFO", "The run's table of objects (<scene>_instances.json) is written once "
                    "every frame is done") in said
    assert not (tmp_path / f"{scene.name}_instances.json").exists()
    assert len(list(tmp_path.glob("*.pcd"))) == 2
    assert scene.frame_current == 1


def test_fov_follows_a_preset_set_by_id(scene):
    obj = add_lidar_op("velodyne_vlp16")
    obj.rls_lidar.preset_id = "robosense_m1"  # scripts may set the id directly
    fov = next(c for c in obj.children if c.get("rls_fov"))
    assert fov["rls_fov_preset"] == "robosense_m1"
    assert obj.rls_lidar.preset == "robosense_m1"


def test_every_property_and_operator_option_has_a_tooltip(scene):
    from rls_addon import operators, properties

    missing = []
    for cls in properties.CLASSES + operators.CLASSES:
        if issubclass(cls, bpy.types.Operator):
            mod, op = cls.bl_idname.split(".")
            props = getattr(getattr(bpy.ops, mod), op).get_rna_type().properties
        else:
            props = cls.bl_rna.properties
        for p in props:
            if p.identifier in ("rna_type", "name") and not issubclass(cls, bpy.types.Operator):
                continue  # PropertyGroup's own
            if p.identifier != "rna_type" and not p.description.strip():
                missing.append(f"{cls.__name__}.{p.identifier}")
    assert not missing


def test_scan_operators_that_make_objects_are_undoable(scene):
    from rls_addon import operators

    for cls in (operators.scan.RLS_OT_scan_frame, operators.scan.RLS_OT_scan_all,
                operators.scan.RLS_OT_scan_range, operators.metrics.RLS_OT_compute_metrics,
                operators.objects.OBJECT_OT_rls_add_lidar,
                operators.objects.OBJECT_OT_rls_add_infralob):
        assert "UNDO" in cls.bl_options, cls.__name__


@pytest.mark.parametrize("op_name", ["RLS_OT_scan_frame", "RLS_OT_scan_all"])
def test_single_frame_scans_show_progress_and_cancel_like_the_range(scene, tmp_path, op_name):
    """Scan Frame and Scan All LiDARs run through the same modal loop as Scan Frame
    Range: a step per timer event, status text with an estimate, Esc stops."""
    from types import SimpleNamespace

    from rls_addon import operators
    from rls_addon.operators import LAST_RUN

    Op = getattr(operators, op_name)
    labelled_ground()
    add_lidar_op(out=tmp_path, location=(0, 0, 2))
    add_lidar_op(out=tmp_path, location=(4, 0, 2))
    ctx = bpy.context
    reports = []
    fake = SimpleNamespace(_timer=None, write=True, preview=True, overwrite=False,
                           report=lambda kind, msg: reports.append((kind, msg)))
    fake._sensors = lambda c: Op._sensors(fake, c)
    fake._frames = lambda c: Op._frames(fake, c)
    fake._end = lambda c: Op._end(fake, c)
    fake._report = lambda run: Op._report(fake, run)
    fake._status = lambda c, t: Op._status(fake, c, t)
    fake._job = Op._make_run(fake, ctx)
    steps = fake._job.total
    assert steps == (2 if op_name == "RLS_OT_scan_all" else 1)
    assert "0/%d done" % steps in fake._job.status()
    ctx.window_manager.progress_begin(0, steps)
    timer = SimpleNamespace(type="TIMER")
    if steps == 2:
        assert Op.modal(fake, ctx, timer) == {"RUNNING_MODAL"}
        assert "1/2 done" in fake._job.status()
        assert Op.modal(fake, ctx, SimpleNamespace(type="ESC")) == {"CANCELLED"}
        assert LAST_RUN["cancelled"] and LAST_RUN["steps_done"] == 1
        assert len(list(tmp_path.glob("*.pcd"))) == 1
    else:
        assert Op.modal(fake, ctx, timer) == {"FINISHED"}
        assert not LAST_RUN["cancelled"] and len(list(tmp_path.glob("*.pcd"))) == 1


def test_batch_command_is_the_command_line_of_the_frame_range(scene, tmp_path):
    """What Copy Batch Command gives runs where the zip was installed: Blender in the
    background with the extension's rls command (it once gave python -m rls_addon, which
    only a checkout with the bpy module can run); the same frames and LiDAR; it parses."""
    import shlex

    from rls_addon.cli import build_parser
    from rls_addon.operators.scan import batch_command

    labelled_ground()
    add_lidar_op(out=tmp_path)
    scene.frame_start, scene.frame_end, scene.frame_step = 5, 40, 5
    blend = tmp_path / "my scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    text = batch_command(bpy.context, all_lidars=False)
    assert text == (f"blender -b '{blend}' -c rls scan --frames 5-40:5 --sensor LiDAR "
                    "--resume")
    words = shlex.split(text)
    args = build_parser().parse_args(words[words.index("rls") + 1:])
    assert (args.command, args.frames, args.sensor, args.resume) == ("scan", "5-40:5",
                                                                     ["LiDAR"], True)
    # and it runs: 'blender' here is the stand-in of tests/cli (Blender as the bpy module)
    import subprocess
    import sys
    from pathlib import Path

    standin = Path(__file__).resolve().parents[1] / "cli" / "blender_standin.py"
    proc = subprocess.run([sys.executable, str(standin), *words[1:]], capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(list(tmp_path.glob("*_LiDAR_0000[0-4][05].pcd"))) == 8
    from rls_addon.operators import LAST_RUN

    assert bpy.ops.rls.batch_command() == {"FINISHED"}
    assert LAST_RUN["batch_command"].startswith("blender -b ")
    assert LAST_RUN["batch_command"].endswith("-c rls scan --frames 5-40:5 --resume")


def test_scan_frame_refuses_to_replace_files_unless_overwrite(scene, tmp_path):
    """Scan Frame once replaced the files of an earlier scan without a word, where rls
    scan refuses: it refuses too, before scanning, naming the file and the option."""
    from rls_addon.operators import LAST_RUN

    labelled_ground()
    add_lidar_op(out=tmp_path)
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    cloud = tmp_path / "Scene_LiDAR_000001.pcd"
    before = cloud.read_bytes()
    cloud.write_bytes(b"an earlier scan's file")
    with pytest.raises(RuntimeError, match="already exists .*Overwrite Files"):
        bpy.ops.rls.scan_frame()
    assert cloud.read_bytes() == b"an earlier scan's file"
    with pytest.raises(RuntimeError, match="already exists"):
        bpy.ops.rls.scan_range(use_scene_range=False, frame_start=1, frame_end=1)
    assert bpy.ops.rls.scan_frame(overwrite=True) == {"FINISHED"}
    assert cloud.read_bytes() == before and LAST_RUN["paths"] == [str(cloud)]
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}  # a preview writes nothing
