"""*File > Export > RLS Dataset* in the bpy module: it is in the export menu, writes a
dataset, refuses an earlier export's files unless told, and from the UI runs modal with
a progress bar and Esc (driven here with synthetic events). That it writes what ``rls
dataset`` writes: tests/cli/test_ui_matches_cli.py."""

from types import SimpleNamespace

import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground


def test_export_writes_refuses_then_replaces(scene, tmp_path):
    labelled_ground()
    add_lidar_op(preset="livox_mid40", location=(0, 0, 3))
    out = tmp_path / "ds"
    kw = dict(directory=str(out), layout="kitti", use_scene_range=False, frame_start=1,
              frame_end=3)
    assert bpy.ops.rls.export_dataset(**kw) == {"FINISHED"}
    assert sorted(p.name for p in (out / "LiDAR" / "points").iterdir()) == [
        "000001.npy", "000002.npy", "000003.npy"]
    with pytest.raises(RuntimeError, match="already exists .*Resume .*Overwrite"):
        bpy.ops.rls.export_dataset(**kw)
    assert bpy.ops.rls.export_dataset(overwrite=True, **kw) == {"FINISHED"}
    assert bpy.ops.rls.export_dataset(resume=True, **kw) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="Choose the dataset folder"):
        bpy.ops.rls.export_dataset(layout="kitti")
    with pytest.raises(RuntimeError, match="No LiDAR is selected"):
        bpy.ops.object.select_all(action="DESELECT")
        bpy.ops.rls.export_dataset(selected_only=True, **kw)


def test_export_is_in_the_file_menu_and_runs_modal(scene, tmp_path):
    from rls_addon.operators import LAST_RUN
    from rls_addon.operators.dataset import RLS_OT_export_dataset as Op
    from rls_addon.operators.dataset import draw_export_menu

    log = []
    draw_export_menu(SimpleNamespace(layout=SimpleNamespace(
        operator=lambda idname, **kw: log.append(idname))), bpy.context)
    assert log == ["rls.export_dataset"]
    labelled_ground()
    add_lidar_op(preset="livox_mid40", location=(0, 0, 3))
    reports = []
    fake = SimpleNamespace(_timer=None, directory=str(tmp_path / "ds"), layout="opv2v",
                           use_scene_range=False, frame_start=1, frame_end=4, frame_step=1,
                           selected_only=False, classes="vehicle", use_seed=False, seed=0,
                           intensity="0-1", points_format="npy", level=False, min_points=1,
                           val_share=0.2, split_seed=0, overwrite=False, resume=False,
                           report=lambda kind, msg: reports.append((kind, msg)))
    for name in ("_end", "_status", "_report", "settings", "_make_run"):
        setattr(fake, name, getattr(Op, name).__get__(fake))
    ctx = bpy.context
    fake._job = fake._make_run(ctx)
    ctx.window_manager.progress_begin(0, fake._job.total)
    assert Op.modal(fake, ctx, SimpleNamespace(type="TIMER")) == {"RUNNING_MODAL"}
    assert "1/4 done" in fake._job.status()
    assert Op.modal(fake, ctx, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    assert LAST_RUN["cancelled"] and LAST_RUN["frames_done"] == [1]
    said = {(next(iter(k)), m) for k, m in reports}
    assert ("WARNING", "Export cancelled: 1 of 4 frames completed, 1 files written") in said
    assert ("INFO", "The dataset's own files: the scenario's description (<scene>.rls.json) "
                    "is written once every frame is done; export again with Resume ticked "
                    "to finish") in said
    assert scene.frame_current == 1
