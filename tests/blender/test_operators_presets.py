"""Preset operators in background mode: apply, save, import, export, delete; presets are
validated TOML data, never code; built-in presets are read-only."""

import os

import pytest

from .conftest import bpy
from .ops_helpers import add_lidar_op, labelled_ground, user_dir  # noqa: F401 (fixture)


def _enum_ids():
    from rls_addon.properties import preset_items

    return [it[0] for it in preset_items(None, None) if it and it[0]]


def test_preset_menu_lists_builtin_presets_grouped_by_family(scene, user_dir):
    from rls_addon.properties import preset_items

    items = preset_items(None, None)
    headers = [it[1] for it in items if it and not it[0]]
    assert headers == ["Spinning", "MEMS", "Risley"]  # no custom presets shipped
    ids = _enum_ids()
    assert "velodyne_vlp16" in ids and "livox_mid40" in ids and "robosense_m1" in ids
    assert len(ids) == len(set(ids))
    numbers = [it[4] for it in items if it and it[0]]
    assert len(numbers) == len(set(numbers))


def test_apply_preset_to_the_active_lidar(scene, user_dir):
    obj = add_lidar_op("generic_uniform32")
    assert bpy.ops.rls.preset_apply(preset="hesai_pandar64") == {"FINISHED"}
    assert obj.rls_lidar.preset == "hesai_pandar64" == obj.rls_lidar.preset_id
    with pytest.raises(RuntimeError, match="unknown device preset 'no_such_device'"):
        bpy.ops.rls.preset_apply(preset="no_such_device")
    bpy.context.view_layer.objects.active = None
    with pytest.raises(RuntimeError, match="Select a LiDAR object"):
        bpy.ops.rls.preset_apply(preset="velodyne_vlp16")


def test_save_user_preset_with_overrides_and_scan_with_it(scene, user_dir, tmp_path):
    from rls_addon.core.device.presets import load_preset
    from rls_addon.operators import LAST_RUN

    labelled_ground()
    obj = add_lidar_op("velodyne_vlp16", out=tmp_path / "out")
    s = obj.rls_lidar
    s.use_max_range, s.max_range = True, 30.0
    s.use_noise_sigma, s.noise_sigma = True, 0.01
    assert bpy.ops.rls.preset_save(name="My VLP-16 (30 m)") == {"FINISHED"}
    path = user_dir / "my_vlp-16_30_m.toml"
    assert path.is_file()
    p = load_preset(path)
    assert p.name == "My VLP-16 (30 m)" and p.family == "spinning"
    assert p.range.max_m == 30.0 and p.range.noise_sigma_m == 0.01
    assert "velodyne" in p.source.lower() or "vlp" in p.source.lower()
    assert "my_vlp-16_30_m" in _enum_ids()
    assert s.preset == "my_vlp-16_30_m"
    s.use_max_range = s.use_noise_sigma = False
    assert bpy.ops.rls.scan_frame() == {"FINISHED"}
    assert LAST_RUN["points"] > 1000
    # the same id again needs overwrite
    with pytest.raises(RuntimeError, match="already exists"):
        bpy.ops.rls.preset_save(name="My VLP-16 (30 m)")
    assert bpy.ops.rls.preset_save(name="My VLP-16 (30 m)", overwrite=True) == {"FINISHED"}
    # the id of a built-in preset is refused
    with pytest.raises(RuntimeError, match="built-in preset id"):
        bpy.ops.rls.preset_save(name="x", preset_id="velodyne_vlp16")
    with pytest.raises(RuntimeError, match="not a usable preset id"):
        bpy.ops.rls.preset_save(name="x", preset_id="Bad Id!")


def test_export_then_import_round_trip(scene, user_dir, tmp_path):
    from rls_addon.core.device.presets import get_preset, load_preset

    obj = add_lidar_op("ouster_os1_64")
    dest = tmp_path / "share" / "os1.toml"
    assert bpy.ops.rls.preset_export(filepath=str(dest)) == {"FINISHED"}
    assert dest.is_file()
    exported = load_preset(dest)
    assert exported.id == "ouster_os1_64"
    # give it a new id, as a colleague would, and import it
    text = dest.read_text().replace('id = "ouster_os1_64"', 'id = "os1_team"', 1)
    mine = tmp_path / "os1_team.toml"
    mine.write_text(text)
    assert bpy.ops.rls.preset_import(filepath=str(mine)) == {"FINISHED"}
    assert (user_dir / "os1_team.toml").is_file()
    assert "os1_team" in _enum_ids() and obj.rls_lidar.preset == "os1_team"
    a, b = get_preset("ouster_os1_64"), load_preset(user_dir / "os1_team.toml")
    assert (a.pattern().directions == b.pattern().directions).all()


def test_import_refuses_a_builtin_id(scene, user_dir, tmp_path):
    dest = tmp_path / "vlp.toml"
    add_lidar_op("velodyne_vlp16")
    assert bpy.ops.rls.preset_export(filepath=str(dest)) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="vlp.toml: key 'id'.*built-in"):
        bpy.ops.rls.preset_import(filepath=str(dest))
    assert not list(user_dir.glob("*.toml"))


@pytest.mark.parametrize("body, key", [
    ('frequency_hz = "fast"', "frequency_hz"),
    ("frequency_hz = 10.0\nwarp_drive = true", "warp_drive"),
])
def test_malformed_preset_import_names_file_and_key(scene, user_dir, tmp_path, body, key):
    src = tmp_path / "broken.toml"
    src.write_text('schema = 1\nid = "broken"\nname = "Broken"\nfamily = "spinning"\n'
                   f'source = "test"\n{body}\n[range]\nmax_m = 100.0\n'
                   '[scan]\nchannels = 16\nupper_fov_deg = 15.0\nlower_fov_deg = -15.0\n'
                   'horizontal_resolution_deg = 0.2\n')
    with pytest.raises(RuntimeError) as err:
        bpy.ops.rls.preset_import(filepath=str(src))
    msg = str(err.value)
    assert str(src) in msg and key in msg, msg
    assert not list(user_dir.glob("*.toml"))


def test_import_of_non_toml_and_python_is_refused_and_never_run(scene, user_dir, tmp_path):
    marker = tmp_path / "ran.txt"
    evil = tmp_path / "evil.toml"
    evil.write_text(f"import os\nopen({str(marker)!r}, 'w').write('x')\n")
    with pytest.raises(RuntimeError, match="evil.toml: not valid TOML"):
        bpy.ops.rls.preset_import(filepath=str(evil))
    assert not marker.exists()
    with pytest.raises(RuntimeError, match="preset file not found"):
        bpy.ops.rls.preset_import(filepath=str(tmp_path / "missing.toml"))
    with pytest.raises(RuntimeError, match="Choose a preset file"):
        bpy.ops.rls.preset_import(filepath="")


def test_import_calibration_builds_on_the_active_lidars_preset(scene, user_dir, tmp_path):
    from pathlib import Path

    from rls_addon.core.device.presets import load_preset

    fix = Path(__file__).resolve().parents[1] / "fixtures" / "calibration"
    obj = add_lidar_op("hesai_pandar64")
    assert bpy.ops.rls.preset_import_calibration(
        filepath=str(fix / "nebula_pandar64.csv")) == {"FINISHED"}
    pid = "hesai_pandar64_nebula_pandar64"
    p = load_preset(user_dir / f"{pid}.toml")
    assert (user_dir / "tables" / f"{pid}.csv").is_file()
    assert p.table.elevations_deg[0] == 14.9 and "nebula_pandar64.csv (sha256" in p.source
    assert pid in _enum_ids() and obj.rls_lidar.preset == pid
    # a file of another vendor for this base: refused, named, nothing written
    with pytest.raises(RuntimeError, match="nebula_vlp16.yaml: the file is a Velodyne"):
        bpy.ops.rls.preset_import_calibration(filepath=str(fix / "nebula_vlp16.yaml"),
                                              base="hesai_pandar64", preset_id="wrong")
    assert not (user_dir / "wrong.toml").exists()
    with pytest.raises(RuntimeError, match="Choose a calibration file"):
        bpy.ops.rls.preset_import_calibration(filepath="")


def test_delete_builtin_is_refused_user_preset_is_deleted(scene, user_dir):
    from rls_addon.core.device.presets import builtin_presets_dir

    obj = add_lidar_op("velodyne_vlp16")
    with pytest.raises(RuntimeError, match="built-in preset and read-only"):
        bpy.ops.rls.preset_delete(preset="velodyne_vlp16")
    assert (builtin_presets_dir() / "velodyne_vlp16.toml").is_file()
    assert bpy.ops.rls.preset_save(name="Temp") == {"FINISHED"}
    assert (user_dir / "temp.toml").is_file() and obj.rls_lidar.preset_id == "temp"
    assert bpy.ops.rls.preset_delete(preset="temp") == {"FINISHED"}
    assert not (user_dir / "temp.toml").exists()
    assert "temp" not in _enum_ids()
    with pytest.raises(RuntimeError, match="no user preset 'temp'"):
        bpy.ops.rls.preset_delete(preset="temp")
    # the LiDAR still names the deleted preset: scanning says so clearly
    with pytest.raises(RuntimeError, match="unknown device preset 'temp'"):
        bpy.ops.rls.scan_frame(write=False)


def test_a_broken_user_file_does_not_hide_the_others(scene, user_dir):
    add_lidar_op("velodyne_vlp16")
    assert bpy.ops.rls.preset_save(name="Good One") == {"FINISHED"}
    (user_dir / "zzz_broken.toml").write_text("id = [")
    assert bpy.ops.rls.preset_refresh() == {"FINISHED"}
    from rls_addon.blender import preset_catalog

    assert "good_one" in _enum_ids()
    assert any("zzz_broken.toml" in e for e in preset_catalog.errors())
    assert bpy.ops.rls.scan_frame(write=False) == {"FINISHED"}  # built-in and user still resolve


def test_an_unknown_preset_names_the_user_files_that_did_not_load(scene, user_dir):
    """Issue 31: a LiDAR naming a user preset whose file is broken used to hear 'user
    presets: none', never why."""
    add_lidar_op("velodyne_vlp16")
    user_dir.mkdir(parents=True, exist_ok=True)
    (user_dir / "mine.toml").write_text('schema = 1\nid = "mine"\nname = "Mine"\n')
    assert bpy.ops.rls.preset_refresh() == {"FINISHED"}
    bpy.context.active_object.rls_lidar["preset_id"] = "mine"
    with pytest.raises(RuntimeError, match=r"could not be read.*mine\.toml.*family"):
        bpy.ops.rls.scan_frame(write=False)


def test_default_user_folder_from_the_source_tree(addon, monkeypatch):
    from rls_addon.blender import preset_catalog

    monkeypatch.delenv(preset_catalog.ENV_USER_DIR, raising=False)
    preset_catalog.set_user_dir(None)
    assert preset_catalog._package() == "rls_addon"  # not under bl_ext
    d = preset_catalog.user_dir()
    assert os.path.isdir(d) and d.endswith(os.path.join("rls_addon", "presets"))
    monkeypatch.setenv(preset_catalog.ENV_USER_DIR, "/tmp/rls_env_presets_test")
    assert preset_catalog.user_dir(create=False) == "/tmp/rls_env_presets_test"
