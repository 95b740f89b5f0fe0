"""The device families, one ``Family`` entry each: what the core (a preset's ``[scan]``
checked, its pattern built) and the UI (the Add > LiDAR menus, the LiDAR panel) know of
a family, in one place.

Adding a family is one module (its ``[scan]`` keys, ``check`` and ``build``, like
``risley.py``) and one entry: ``FAMILIES.add(Family(...))``; a preset file then names
it in ``family = "..."``. ``FAMILIES.remove(id)`` takes it out again.
"""

from dataclasses import dataclass
from typing import Callable

from ...choices import Registry
from . import custom, mems, risley, spinning


@dataclass(frozen=True)
class Family:
    """One scanning family.

    id                the preset file's ``family`` (and the menu's name)
    label, icon       the UI's name and Blender icon of the family
    description       one line for tooltips and listings
    scan_keys         the keys its ``[scan]`` table may hold (others are errors)
    check             ``check(scan, where, frequency_hz, base_dir) -> (rays, extras)``:
                      validates ``[scan]`` (errors are ``PresetError``s naming ``where``,
                      files resolved against ``base_dir``, which may be None); ``rays``
                      per frame (None: known only once built), ``extras`` the
                      ``DevicePreset`` fields it resolved (a spinning preset's ``table``
                      and ``firing_times``), {} for most
    build             ``build(preset, frame) -> ScanPattern``: the rays of one frame
    changes_per_frame True when frame k's pattern differs from frame 0's (prisms and
                      mirrors that keep moving); False: one pattern for every frame
    """

    id: str
    label: str
    icon: str
    description: str
    scan_keys: frozenset
    check: Callable
    build: Callable
    changes_per_frame: bool = False


FAMILIES = Registry("device family", [
    Family("spinning", "Spinning", "LIGHTPROBE_SPHERE",
           "Spinning multi-beam heads (Velodyne, Hesai, Ouster, RoboSense)",
           spinning.SCAN_KEYS, spinning.check, spinning.build),
    Family("mems", "MEMS", "LIGHTPROBE_PLANE", "MEMS mirror scanners (RoboSense M1, Blickfeld)",
           mems.SCAN_KEYS, mems.check, mems.build, changes_per_frame=True),
    Family("risley", "Risley", "LIGHTPROBE_VOLUME", "Risley prism scanners (Livox)",
           risley.SCAN_KEYS, risley.check, risley.build, changes_per_frame=True),
    Family("custom", "Custom", "FILE_TEXT", "A pattern read from a CSV file of rays",
           custom.SCAN_KEYS, custom.check, custom.build),
])


def family_of(preset):
    """The ``Family`` of a ``DevicePreset`` (``SettingsError`` when it is not registered)."""
    return FAMILIES.get(preset.family)
