"""Preset files: every shipped preset loads, hostile/malformed files are rejected with
the file and key named, user presets round-trip through save/import/export."""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from rls_addon.core.errors import OutputError, PresetError
from rls_addon.core.device.presets import (
    builtin_presets,
    builtin_presets_dir,
    get_preset,
    load_preset,
    pattern_span,
    preset_from_dict,
)
from rls_addon.core.device.user_presets import (
    delete_user_preset,
    export_preset,
    import_preset,
    save_user_preset,
    user_presets,
)

EXPECTED = {
    "velodyne_vlp16", "velodyne_vlp32c", "velodyne_hdl32e", "velodyne_hdl64e",
    "hesai_pandar64", "hesai_pandar40p", "hesai_pandar40m", "hesai_pandarqt", "hesai_pandarxt32",
    "hesai_pandar128", "ouster_os1_64", "ouster_os1_128", "robosense_ruby128", "robosense_bpearl",
    "robosense_m1", "robosense_rs16", "robosense_rs32", "livox_horizon", "livox_mid40",
    "livox_mid70", "livox_avia", "livox_tele15", "livox_hap", "generic_uniform32",
}

GOOD = """id = "t"
name = "T"
family = "spinning"
source = "test"
frequency_hz = 10.0
[range]
max_m = 100.0
[scan]
channels = 4
upper_fov_deg = 5.0
lower_fov_deg = -5.0
points_per_second = 14400
"""


def test_all_builtin_presets_load():
    presets = builtin_presets()
    assert EXPECTED <= set(presets)
    for p in presets.values():
        assert p.source.strip() and p.family in ("spinning", "mems", "risley")
        assert p.rays_per_frame == len(p.pattern()) or p.rays_per_frame == pytest.approx(
            len(p.pattern()), rel=0.01)
        assert np.allclose(np.linalg.norm(p.pattern().directions, axis=1), 1.0)


def test_preset_files_reference_only_relative_tables():
    import tomllib

    for f in builtin_presets_dir().glob("*.toml"):
        assert "/work" not in f.read_text()
        table = tomllib.loads(f.read_text())["scan"].get("table")
        if table is not None:
            assert table.startswith("tables/") and ".." not in table
            assert (builtin_presets_dir() / table).is_file()


def test_lookup_by_name_and_alias():
    assert get_preset("Velodyne VLP-16").id == "velodyne_vlp16"
    assert get_preset("vlp-16").id == "velodyne_vlp16"
    assert get_preset("HESAI_PANDAR64").id == "hesai_pandar64"
    with pytest.raises(PresetError, match="unknown device preset"):
        get_preset("no such lidar")


def write(tmp_path, text, name="bad.toml"):
    f = tmp_path / name
    f.write_text(text)
    return f


def edit(text, old, new):
    assert old in text
    return text.replace(old, new)


HOSTILE = [
    ("missing key", edit(GOOD, 'source = "test"\n', ""), "'source'"),
    ("wrong type", edit(GOOD, "frequency_hz = 10.0", 'frequency_hz = "fast"'), "'frequency_hz'"),
    ("nan", edit(GOOD, "max_m = 100.0", "max_m = nan"), "'max_m'"),
    ("inf", edit(GOOD, "frequency_hz = 10.0", "frequency_hz = inf"), "'frequency_hz'"),
    ("negative range", edit(GOOD, "max_m = 100.0", "max_m = -5.0"), "'max_m'"),
    ("min above max", edit(GOOD, "max_m = 100.0", "max_m = 100.0\nmin_m = 200.0"), "'min_m'"),
    ("too many rays", edit(GOOD, "points_per_second = 14400", "points_per_second = 2e8"),
     "rays per frame"),
    ("huge channel count", edit(GOOD, "channels = 4", "channels = 100000"), "'channels'"),
    ("bool as number", edit(GOOD, "channels = 4", "channels = true"), "'channels'"),
    ("unknown family", edit(GOOD, 'family = "spinning"', 'family = "laser-cannon"'), "'family'"),
    ("unknown key", edit(GOOD, "[range]", 'exec = "import os"\n[range]'), "'exec'"),
    ("unknown scan key", edit(GOOD, "channels = 4", "channels = 4\nchanels = 5"), "'chanels'"),
    ("absolute table", edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                            'table = "/etc/passwd"\nazimuth_convention = "hesai"'), "'table'"),
    ("dotdot table", edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                          'table = "../secret.csv"\nazimuth_convention = "hesai"'), "'table'"),
    ("missing table", edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                           'table = "tables/none.csv"\nazimuth_convention = "hesai"'), "'table'"),
    ("bad convention", edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                            'elevations_deg = [1.0, 2.0]\nazimuth_convention = "sideways"'),
     "'azimuth_convention'"),
    ("offsets length", edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                            'elevations_deg = [1.0, 2.0]\nazimuth_offsets_deg = [1.0]'),
     "'azimuth_offsets_deg'"),
    ("two rates", edit(GOOD, "points_per_second = 14400",
                       "points_per_second = 14400\nhorizontal_resolution_deg = 0.2"), "points_per_second"),
    ("firing too long", edit(GOOD, "points_per_second = 14400",
                             "firing_cycle_us = 50.0\nfiring_step_us = 20.0"), "firing"),
    ("path-like id", edit(GOOD, 'id = "t"', 'id = "../../evil"'), "'id'"),
    ("missing scan", GOOD.split("[scan]")[0], "[scan]"),
    ("scan not a table", 'scan = "x"\n' + GOOD.split("[scan]")[0], "[scan]"),
    ("risley bad index", 'id = "r"\nname = "R"\nfamily = "risley"\nsource = "s"\nfrequency_hz = 10.0\n'
                         '[range]\nmax_m = 10.0\n[scan]\npulse_rate_hz = 1000.0\nrotation_hz = [1.0, 2.0]\n'
                         'wedge_deg = [1.0]\nrefractive_index = 1.5\n', "'wedge_deg'"),
    ("mems zones", 'id = "m"\nname = "M"\nfamily = "mems"\nsource = "s"\nfrequency_hz = 10.0\n'
                   '[range]\nmax_m = 10.0\n[scan]\nmodel = "lissajous_zones"\npoints_per_second = 1e5\n'
                   'h_mirror_hz = 1.0\nv_mirror_hz = 1.0\nh_amplitude_deg = 1.0\nupper_amplitude_deg = 1.0\n'
                   'lower_amplitude_deg = 1.0\nzones = [[0.0, 1.0]]\n', "'zones'"),
    ("schema version", "schema = 99\n" + GOOD, "'schema'"),
    # an integer past Python's 4300-digit limit: tomllib's ValueError, not a traceback
    ("huge integer", edit(GOOD, "frequency_hz = 10.0", "frequency_hz = " + "1" * 5000),
     "not a readable TOML file"),
]


@pytest.mark.parametrize("label,text,key", HOSTILE, ids=[h[0] for h in HOSTILE])
def test_hostile_files_name_file_and_key(tmp_path, label, text, key):
    f = write(tmp_path, text)
    with pytest.raises(PresetError) as exc:
        load_preset(f)
    msg = str(exc.value)
    assert str(f) in msg and key in msg, msg


def test_not_toml_and_not_found(tmp_path):
    f = write(tmp_path, "import os\nos.system('rm -rf /')\n")
    with pytest.raises(PresetError, match="not valid TOML"):
        load_preset(f)
    with pytest.raises(PresetError, match="not found"):
        load_preset(tmp_path / "missing.toml")
    big = write(tmp_path, "# " + "x" * 3_000_000, "big.toml")
    with pytest.raises(PresetError, match="big.toml"):
        load_preset(big)


def test_bad_table_content_names_line(tmp_path):
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "t.csv").write_text("channel,elevation_deg\n1,5.0\n2,oops\n")
    f = write(tmp_path, edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                             'table = "tables/t.csv"\nazimuth_convention = "hesai"'))
    with pytest.raises(PresetError, match=r"bad.toml.*t.csv.*line 3.*elevation_deg"):
        load_preset(f)


def test_table_symlink_outside_is_rejected(tmp_path):
    outside = tmp_path / "outside.csv"
    outside.write_text("channel,elevation_deg\n1,5.0\n")
    d = tmp_path / "p"
    (d / "tables").mkdir(parents=True)
    (d / "tables" / "link.csv").symlink_to(outside)
    f = write(d, edit(GOOD, "channels = 4\nupper_fov_deg = 5.0\nlower_fov_deg = -5.0",
                      'table = "tables/link.csv"\nazimuth_convention = "hesai"'))
    with pytest.raises(PresetError, match="outside"):
        load_preset(f)


def test_preset_from_dict_without_file():
    import tomllib

    p = preset_from_dict(tomllib.loads(GOOD), "<memory>")
    assert len(p.pattern()) == 1440
    with pytest.raises(PresetError, match="<memory>.*'table'"):
        preset_from_dict({**tomllib.loads(GOOD), "scan": {"table": "tables/x.csv"}}, "<memory>")


def test_pattern_cached_and_read_only():
    p = get_preset("velodyne_vlp16")
    assert p.pattern() is p.pattern()
    with pytest.raises(ValueError):
        p.pattern().times[0] = 1.0


def test_pattern_span_continues_times():
    p = get_preset("velodyne_vlp16")
    t, d, c = pattern_span(p, 0.25)
    assert np.all(np.diff(t) >= 0) and t[-1] < 0.25 and t[-1] > 0.2499
    assert len(t) == pytest.approx(2.5 * len(p.pattern()), rel=0.01)


@pytest.mark.parametrize("pid", ["hesai_pandar64", "livox_avia", "robosense_m1", "generic_uniform32"])
def test_user_preset_round_trip(tmp_path, pid):
    import dataclasses

    builtin = get_preset(pid)
    user = tmp_path / "user"
    with pytest.raises(PresetError, match="built-in preset id"):  # never shadows it
        save_user_preset(builtin, user)
    shared_builtin = export_preset(builtin, tmp_path / "builtin.toml")  # sharing is fine
    with pytest.raises(PresetError, match="built-in preset id"):
        import_preset(shared_builtin, user)
    src = dataclasses.replace(builtin, id=f"{pid}_team")
    pid = src.id
    path = save_user_preset(src, user)
    assert path == user / f"{pid}.toml"
    assert pid in user_presets(user)
    with pytest.raises(OutputError):
        save_user_preset(src, user)
    # export, move the file to "another machine", import there
    shared = export_preset(src, tmp_path / "share" / "mine.toml")
    text = shared.read_text()
    assert str(tmp_path) not in text and "/work" not in text and "table =" not in text
    other = tmp_path / "elsewhere"
    other.mkdir()
    moved = Path(shutil.move(str(shared), other / "mine.toml"))
    got = import_preset(moved, tmp_path / "user2")
    assert got.id == src.id and got.source == src.source and got.range == src.range
    a, b = src.pattern(), got.pattern()
    assert len(a) == len(b)
    assert np.allclose(a.directions, b.directions, atol=1e-12) and np.array_equal(a.times, b.times)
    assert get_preset(pid, user_dir=tmp_path / "user2").id == pid
    delete_user_preset(pid, user)
    assert pid not in user_presets(user)
    with pytest.raises(PresetError, match="read-only"):
        delete_user_preset(builtin.id, user)


def test_custom_preset_export_carries_pattern(tmp_path):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "scan.csv").write_text("0,0,0,0\n0.01,1,2,3\n")
    (d / "c.toml").write_text('id = "c1"\nname = "C"\nfamily = "custom"\nsource = "s"\n'
                             'frequency_hz = 10.0\n[range]\nmax_m = 5.0\n[scan]\nfile = "scan.csv"\n')
    p = load_preset(d / "c.toml")
    out = export_preset(p, tmp_path / "out" / "c.toml")
    assert (tmp_path / "out" / "c.pattern.csv").is_file()
    assert len(load_preset(out).pattern()) == 2
    saved = import_preset(out, tmp_path / "user")
    assert Path(saved.path).parent == tmp_path / "user"
    assert len(saved.pattern()) == 2
    # a --user-dir that names a file: said so, where it only said 'File exists'
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OutputError, match="afile: not a folder; give --user-dir the folder"):
        import_preset(out, tmp_path / "afile")
    assert (tmp_path / "afile").read_text() == "x"


def test_validation_does_not_generate_huge_patterns(tmp_path, monkeypatch):
    # 1e8 points/s at 10 Hz is 1e7 rays a frame, the limit (a multiple of the 4 channels):
    # accepted, its count estimated from the rate, and no pattern built to find it out.
    import dataclasses

    import rls_addon.core.device.presets as presets_module
    from rls_addon.core.device.families import FAMILIES

    def no_pattern(*args, **kwargs):
        raise AssertionError("validation built a pattern")

    # the spinning family's entry, as validation finds it, builds no pattern
    spinning = FAMILIES.get("spinning")
    monkeypatch.setattr(presets_module, "family_of",
                        lambda preset: dataclasses.replace(spinning, build=no_pattern))
    f = write(tmp_path, edit(GOOD, "points_per_second = 14400", "points_per_second = 1.0e8"))
    p = load_preset(f)
    assert p.rays_per_frame == 10_000_000
    assert math.isfinite(p.frequency_hz)
    # one more point a second is over the limit: refused, not clipped to it
    f = write(tmp_path, edit(GOOD, "points_per_second = 14400", "points_per_second = 1.00000004e8"))
    with pytest.raises(PresetError, match="exceeds the limit of 10000000"):
        load_preset(f)


def test_a_broken_or_doubled_user_preset_hides_no_other(tmp_path):
    """A command-line audit found one stray file in the user folder (two files of id
    'mine') blocking 'presets show' and 'export' of every preset, built-ins included.
    A lookup now finds every preset that loads; the doubled id itself is refused (which
    of the two is meant cannot be told), and a name found nowhere lists the files that
    did not load."""
    import dataclasses

    user = tmp_path / "user"
    mine = dataclasses.replace(get_preset("hesai_pandar64"), id="mine", name="Mine")
    other = dataclasses.replace(get_preset("velodyne_vlp16"), id="other", name="Other")
    save_user_preset(mine, user)
    save_user_preset(other, user)
    export_preset(mine, user / "copy of mine.toml")  # the same id again
    (user / "broken.toml").write_text("schema = 1\nid = 'broken'\n")
    assert get_preset("velodyne_vlp32c", user_dir=user).id == "velodyne_vlp32c"
    assert get_preset("Other", user_dir=user).id == "other"
    with pytest.raises(PresetError, match="id 'mine' already used by"):
        get_preset("mine", user_dir=user)
    with pytest.raises(PresetError, match="unknown device preset 'nothing'.*did not load: "
                                          ".*broken.toml"):
        get_preset("nothing", user_dir=user)
