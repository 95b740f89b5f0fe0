"""What README.md counts and lists agrees with the code: the presets of real sensors
(the generic one, 'not a real device', once made it say 24 for 23) and the commands
``--help`` lists."""

import re
from pathlib import Path

from rls_addon.commands import COMMAND_MODULES
from rls_addon.core.device.presets import builtin_presets

README = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")


def test_real_sensor_count():
    presets = list(builtin_presets().values())
    real = [p for p in presets if "not a real device" not in p.source]
    assert len(real) == len(presets) - 1  # one generic preset
    said = re.search(r"(\d+) presets of real sensors", README)
    assert said and int(said.group(1)) == len(real)


def test_help_commands_listed():
    said = re.search(r"lists every command: (.*?)\.\n", README, re.S).group(1)
    assert re.findall(r"`(\w[\w-]*)`", said) == list(COMMAND_MODULES)
