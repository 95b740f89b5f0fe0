"""Issue 41: a device family and an output format are each one module and one registry
entry. A toy family and a toy format (tests/toy_extensions.py) are added through the
registries alone and work everywhere the core and the command line offer families and
formats: preset files, patterns, ``rls presets list``, ``rls scan --format``'s
choices, a scan run's files (written, read back, resumed); taken out, nothing is left."""

import contextlib
import io

import numpy as np
import pytest

from rls_addon.cli import build_parser, main
from rls_addon.core.choices import Registry
from rls_addon.core.device.families import FAMILIES
from rls_addon.core.device.presets import load_preset, preset_from_dict
from rls_addon.core.errors import PresetError, SettingsError
from rls_addon.core.output.io import read_cloud, read_sidecar
from rls_addon.core.output.io.formats import FORMATS
from rls_addon.core.output.io.writer import CloudWriter
from rls_addon.core.scan.run import ScanRun, SensorJob
from rls_addon.core.scan.settings import LidarSettings, OutputSettings, ScanSettings

from tests import toy_extensions as toy

from .fakes import numpy_factory, street


def _format_choices():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    scan = sub.choices["scan"]
    return next(a for a in scan._actions if a.dest == "format").choices


def _presets_list(user_dir):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["presets", "list", "--user-dir", str(user_dir)])
    return code, out.getvalue(), err.getvalue()


def test_a_registry_refuses_a_taken_or_malformed_id_and_names_the_ids_it_has():
    reg = Registry("widget", [toy.FORMAT])
    with pytest.raises(SettingsError, match="already registered"):
        reg.add(toy.FORMAT)
    with pytest.raises(SettingsError, match="lower-case letters"):
        reg.add(toy.FORMAT.__class__("Bad-Id", "x", "x", ".x"))
    with pytest.raises(SettingsError, match="unknown widget 'nope'; choose one of toy_text"):
        reg.get("nope")
    heard = []
    reg.subscribe(heard.append)
    reg.remove("toy_text")
    assert reg.ids == () and heard == [reg]


def test_a_toy_family_and_format_through_the_registries_alone(tmp_path):
    toy.write_preset(tmp_path / "user")
    assert toy.FAMILY_ID not in FAMILIES and toy.FORMAT_ID not in FORMATS
    assert toy.FORMAT_ID not in _format_choices()
    code, _, err = _presets_list(tmp_path / "user")
    assert code == 1 and "family" in err and "toy_fan" in err  # unknown family: refused
    with toy.registered():
        # the command line offers them
        assert toy.FORMAT_ID in _format_choices()
        code, out, err = _presets_list(tmp_path / "user")
        assert code == 0 and err == ""
        line = next(x for x in out.splitlines() if x.startswith("toy_fan_64"))
        assert line.split()[1] == "toy_fan" and "64 rays/frame" in line
        # the preset file is checked by the family's keys and check
        preset = load_preset(tmp_path / "user" / "toy_fan_64.toml")
        assert (preset.family, preset.rays_per_frame, len(preset.pattern(0))) == ("toy_fan", 64, 64)
        with pytest.raises(PresetError, match=r"\[scan\]: unknown key 'channels'"):
            preset_from_dict({"id": "t", "name": "t", "family": "toy_fan", "source": "s",
                              "frequency_hz": 10.0, "range": {"max_m": 5.0},
                              "scan": {"rays": 4, "fov_deg": 1.0, "channels": 2}})

        # a scan run with the toy device, written in the toy format
        out_dir = tmp_path / "out"
        settings = LidarSettings(preset=preset.id, scan=ScanSettings(noise=False),
                                 output=OutputSettings(directory=str(out_dir),
                                                       format=toy.FORMAT_ID))
        jobs = [SensorJob("pole", settings, preset)]
        scene = street()
        summary = ScanRun(scene, jobs, [1, 2], writer=CloudWriter(scene.name),
                          factory=numpy_factory).run().summary()
        assert summary["scanned"] == 2
        path = out_dir / "fake_pole_000001.toy"
        points = read_cloud(path)  # recognised by its contents, read by its decoder
        side = read_sidecar(path)
        assert side["format"] == toy.FORMAT_ID and side["points"] == len(points) == 64
        assert side["fields"] == list(settings.output.fields)
        # the fan at -30 degrees from 1.5 m over the ground slab's top meets it at 3 m
        rng = np.sqrt(points["x"].astype(float) ** 2 + points["y"] ** 2 + points["z"] ** 2)
        assert np.abs(rng - 3.0).max() < 1e-5
        assert np.abs(points["z"] + 1.5).max() < 1e-5
        # resumed: the files read back and are kept
        again = ScanRun(scene, jobs, [1, 2], writer=CloudWriter(scene.name, resume=True),
                        factory=numpy_factory).run().summary()
        assert (again["scanned"], again["resumed"]) == (0, 2)
    # taken out again: gone from the registries, the choices and the checks
    assert toy.FAMILY_ID not in FAMILIES and toy.FORMAT_ID not in FORMATS
    assert toy.FORMAT_ID not in _format_choices()
    with pytest.raises(SettingsError, match="unknown cloud format 'toy_text'"):
        OutputSettings(format=toy.FORMAT_ID)
    with pytest.raises(PresetError, match="key 'family' must be one of spinning, mems, risley, "
                                          "custom, got 'toy_fan'"):
        load_preset(tmp_path / "user" / "toy_fan_64.toml")
