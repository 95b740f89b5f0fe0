"""``rls scan`` writes what each LiDAR's panels say unless a flag says otherwise, and
every entry point (command line, UI operator, core) makes the same motion decisions."""

import json
import math
import subprocess
import sys

import pytest

from .conftest import ROOT, SCENE_SCRIPT_HEAD, build_blend, one_line_error, rls

SPEED = 5.55   # m/s of the moving box
FPS = 25

BUILD = SCENE_SCRIPT_HEAD + r"""
scene = bpy.context.scene
scene.name = "moving"
scene.render.fps, scene.render.fps_base = FPS, 1.0

box("Ground", (-40, -40, -1.1), (40, 40, -1.0))["rls_label"] = "road"
cube = box("Box", (-1, -1, -1), (1, 1, 1))
for frame, y in ((1, -5.0), (101, -5.0 + SPEED * 100 / FPS)):
    cube.location = (8.0, y, 0.0)
    cube.keyframe_insert("location", frame=frame)
for layer in cube.animation_data.action.layers:
    for strip in layer.strips:
        for bag in strip.channelbags:
            for fc in bag.fcurves:
                for kp in fc.keyframe_points:
                    kp.interpolation = "LINEAR"
lidar = bpy.data.objects.new("LiDAR", None)
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id, s.noise, s.dropout = True, "generic_uniform32", False, False
s.file_format, s.fields = "ply_binary", {"intensity", "range", "ring"}
s.motion, s.substeps = "substeps", 0
s.output_dir = sys.argv[3]
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
""".replace("SPEED", repr(SPEED)).replace("FPS", repr(FPS))

OPERATOR = r"""
import sys, json, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
if not hasattr(bpy.types.Object, "rls_lidar"):
    rls_addon.register()
lidar = bpy.data.objects["LiDAR"]
bpy.context.view_layer.objects.active = lidar
lidar.rls_lidar.output_dir = sys.argv[3]
bpy.context.scene.frame_set(1)
assert bpy.ops.rls.scan_frame() == {"FINISHED"}
"""


@pytest.fixture(scope="module")
def moving_blend(tmp_path_factory):
    d = tmp_path_factory.mktemp("moving")
    return build_blend(d, "moving.blend", BUILD, d / "panel")


def test_scan_writes_what_the_output_panel_says_unless_a_flag_overrides(moving_blend, tmp_path):
    from plyfile import PlyData

    out = tmp_path / "ply"
    proc = rls("scan", moving_blend, "--frames", "1-2", "--out", out)
    assert proc.returncode == 0, proc.stderr
    files = sorted(p.name for p in out.iterdir())
    assert files == ["moving_LiDAR_000001.json", "moving_LiDAR_000001.ply",
                     "moving_LiDAR_000002.json", "moving_LiDAR_000002.ply",
                     "moving_instances.json"]
    ply = PlyData.read(str(out / files[1]))  # plyfile, not our reader, judges the file
    props = [p.name for p in ply["vertex"].properties]
    assert props == ["x", "y", "z", "range", "intensity", "ring"]
    assert len(ply["vertex"]["range"]) > 1000 and ply["vertex"]["range"].min() > 0
    pcd = tmp_path / "pcd"
    proc = rls("scan", moving_blend, "--frames", "1-2", "--out", pcd, "--format", "pcd_binary",
               "--fields", "intensity,label")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.suffix for p in pcd.iterdir()) == [".json", ".json", ".json", ".pcd", ".pcd"]
    head = (pcd / "moving_LiDAR_000001.pcd").read_bytes()[:400].decode("ascii", "replace")
    assert "FIELDS x y z intensity label\n" in head
    # without --out, the LiDAR's own folder (saved in the file) is used
    proc = rls("scan", moving_blend, "--frames", "3", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (moving_blend.parent / "panel" / "moving_LiDAR_000003.ply").is_file()


def test_adaptive_substeps_agree_in_ui_command_line_and_core(moving_blend, tmp_path):
    from rls_addon.core.output.io import read_sidecar
    from rls_addon.core.device.presets import get_preset
    from rls_addon.core.scan.sweep import substep_count

    preset = get_preset("generic_uniform32")
    tol = preset.range.noise_sigma_m or 0.01
    want = substep_count(SPEED * preset.period, tol)  # the core's rule on the known motion
    assert want == math.ceil(SPEED * preset.period / tol) == 56
    cli = tmp_path / "cli"
    assert rls("scan", moving_blend, "--frames", "1", "--out", cli).returncode == 0
    cli_side = read_sidecar(cli / "moving_LiDAR_000001.ply")
    ui = tmp_path / "ui"
    proc = subprocess.run([sys.executable, "-c", OPERATOR, str(ROOT), str(moving_blend), str(ui)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    ui_side = read_sidecar(ui / "moving_LiDAR_000001.ply")
    for side in (cli_side, ui_side):
        assert side["effects"]["motion"] == "substeps" and side["effects"]["substeps"] == 0
        assert side["effects"]["substeps_used"] == want
        assert side["motion"]["rigid"] == ["Box"]
    assert (cli / "moving_LiDAR_000001.ply").read_bytes() == \
        (ui / "moving_LiDAR_000001.ply").read_bytes()
    fixed = tmp_path / "fixed"
    assert rls("scan", moving_blend, "--frames", "1", "--out", fixed, "--substeps", "3").returncode == 0
    assert read_sidecar(fixed / "moving_LiDAR_000001.ply")["effects"]["substeps_used"] == 3


def test_unknown_choices_end_with_one_line_naming_them(moving_blend, tmp_path):
    proc = rls("scan", moving_blend, "--out", tmp_path, "--fields", "intensity,colour")
    assert "unknown point field 'colour'; choose one of intensity, ring" in one_line_error(proc)
    proc = rls("scan", moving_blend, "--out", tmp_path, "--motion", "fast")
    assert proc.returncode == 2 and "invalid choice: 'fast'" in proc.stderr


def test_presets_import_refuses_a_builtin_id(tmp_path):
    shared = tmp_path / "vlp.toml"
    assert rls("presets", "export", "velodyne_vlp16", shared).returncode == 0
    proc = rls("presets", "import", shared, "--user-dir", tmp_path / "user")
    assert "'velodyne_vlp16' is a built-in preset id" in one_line_error(proc)
    assert not (tmp_path / "user").exists() or not list((tmp_path / "user").iterdir())
    json.dumps({})


PANEL_POINT_TYPE = r"""
import sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
if not hasattr(bpy.types.Object, "rls_lidar"):
    rls_addon.register()
s = bpy.data.objects["LiDAR"].rls_lidar
s.point_type, s.file_format, s.crs = "velodyne", "pcd_ascii", "EPSG:25832"
from rls_addon.blender.sensor import read_settings
out = read_settings(bpy.data.objects["LiDAR"]).output
assert (out.point_type, out.format, out.crs) == ("velodyne", "pcd_ascii", "EPSG:25832"), out
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
"""


def test_output_panel_point_type_is_what_scan_writes_unless_a_flag_overrides(moving_blend, tmp_path):
    blend = tmp_path / "velodyne.blend"
    proc = subprocess.run([sys.executable, "-c", PANEL_POINT_TYPE, str(ROOT), str(moving_blend),
                           str(blend)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for args, fields in (((), "x y z intensity ring time"),  # the panel's Velodyne point
                         (("--point-type", "rls"), "x y z range intensity ring")):  # a flag wins
        out = tmp_path / (args[-1] if args else "panel")
        proc = rls("scan", blend, "--frames", "1", "--out", out, *args)
        assert proc.returncode == 0, proc.stderr
        head = (out / "moving_LiDAR_000001.pcd").read_text(errors="replace")[:300]
        assert f"FIELDS {fields}\n" in head, head


def test_a_seed_is_used_whole_and_a_negative_one_refused(demo_run, tmp_path):
    blend = demo_run[0] / "intersection.blend"
    clouds = {}
    for seed in (0, 2 ** 32, 2 ** 64):
        out = tmp_path / str(seed)
        proc = rls("scan", blend, "--frames", "1", "--out", out, "--workers", "1",
                   "--seed", seed)
        assert proc.returncode == 0, proc.stderr
        side = json.loads((out / "intersection_LiDAR_000001.json").read_text())
        assert side["seed"] == seed
        clouds[seed] = (out / "intersection_LiDAR_000001.pcd").read_bytes()
    assert len(set(clouds.values())) == 3
    proc = rls("scan", blend, "--frames", "1", "--out", tmp_path / "neg", "--seed", "-1")
    assert one_line_error(proc) == "rls: error: the seed must be a whole number >= 0, got -1"


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_a_sweep_start_that_is_not_finite_is_one_line(demo_run, tmp_path, value):
    proc = rls("scan", demo_run[0] / "intersection.blend", "--frames", "1", "--out", tmp_path,
               f"--sweep-start={value}")
    assert one_line_error(proc) == ("rls: error: the sweep start (sweep_start_deg, degrees) "
                                    f"must be a finite number, got {float(value)!r}")
    assert not list(tmp_path.iterdir())


def test_a_scene_from_a_newer_blender_is_scanned_with_a_warning(tmp_path):
    """Issue 31: Blender's "expect loss of data" for a file of a newer Blender went to the
    silenced log. The file is one of this Blender's, its header marked 5.2 (as 5.2 would
    write it); the scan still runs and says what may be lost."""
    blend = build_blend(tmp_path, "plain.blend", SCENE_SCRIPT_HEAD + r"""
box("Wall", (8, -5, -1), (9, 5, 3))
lidar = bpy.data.objects.new("Lidar", None)
bpy.context.scene.collection.objects.link(lidar)
lidar.rls_lidar.is_lidar, lidar.rls_lidar.preset_id = True, "velodyne_vlp16"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2], compress=False)
""")
    data = bytearray(blend.read_bytes())
    assert data[:13] == b"BLENDER17-01v" and data[13:17] == b"0500", data[:17]
    newer = tmp_path / "newer.blend"
    newer.write_bytes(data[:13] + b"0502" + data[17:])
    same = rls("scan", blend, "--out", tmp_path / "same", "--format", "ply_binary")
    assert same.returncode == 0 and "newer" not in same.stderr, same.stderr
    proc = rls("scan", newer, "--out", tmp_path / "newer", "--format", "ply_binary")
    assert proc.returncode == 0, proc.stderr
    warning = [ln for ln in proc.stderr.splitlines() if ln.startswith("rls: warning:")]
    assert len(warning) == 1 and "newer.blend" in warning[0] and "Blender 5.2" in warning[0]
