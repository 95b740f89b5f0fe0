"""Device presets as the Blender UI sees them: the shipped presets plus the user's own,
kept in an in-memory catalog so that menus and panels never touch the disk in ``draw()``.

User presets live in ``bpy.utils.extension_path_user(<package>, path="presets")`` when
the add-on runs as an installed extension (``bl_ext.<repo>.rls_addon``). Run from the
source tree, extension_path_user is refused, so a folder under Blender's user config
(or the temp dir) is used instead. ``set_user_dir()`` (or the ``RLS_USER_PRESET_DIR``
environment variable) overrides the folder, for tests and batch jobs.

Presets are TOML data validated on load (``core.presets``); nothing here executes them.
"""

import os
import tempfile
from dataclasses import dataclass

from ..core.errors import PresetError
from ..core.device.families import FAMILIES
from ..core.device.presets import builtin_presets, get_preset, load_preset, readable_presets_in

ENV_USER_DIR = "RLS_USER_PRESET_DIR"

_state = {"override": None, "catalog": None, "errors": []}


def _package():
    """The add-on's top-level package name (``rls_addon`` or ``bl_ext.<repo>.rls_addon``)."""
    return __package__.rpartition(".")[0]


def set_user_dir(path):
    """Use ``path`` for user presets (None: back to the default); refreshes the catalog."""
    _state["override"] = None if path is None else str(path)
    refresh()


def user_dir(create=True):
    """The folder user presets are stored in (created when ``create``)."""
    d = _state["override"] or os.environ.get(ENV_USER_DIR)
    if not d:
        import bpy

        pkg = _package()
        if pkg.startswith("bl_ext."):
            try:
                d = bpy.utils.extension_path_user(pkg, path="presets", create=create)
            except Exception:  # noqa: BLE001 - fall through to the source-tree folder
                d = None
        if not d:
            base = bpy.utils.user_resource("CONFIG") or tempfile.gettempdir()
            d = os.path.join(base, "rls_addon", "presets")
    if create:
        try:
            os.makedirs(d, exist_ok=True)
        except OSError:
            d = os.path.join(tempfile.gettempdir(), "rls_addon_presets")
            os.makedirs(d, exist_ok=True)
    return d


@dataclass(frozen=True)
class Entry:
    """One preset as listed in menus."""

    id: str
    name: str
    family: str
    source: str
    builtin: bool
    path: str
    # the device's lidar modes and its default ([modes] lidar_mode), for the panel's enum
    lidar_modes: tuple = ()
    default_lidar_mode: str = None


def refresh():
    """Re-read the shipped and user presets (call after saving, importing or deleting).
    A broken user preset file does not hide the others: its error is kept in ``errors()``."""
    entries, errors = [], []
    for p in builtin_presets().values():
        entries.append(Entry(p.id, p.name, p.family, p.source, True, str(p.path), *_modes(p)))
    taken = {e.id for e in entries}
    d = user_dir(create=False)
    if os.path.isdir(d):
        found, problems = readable_presets_in(d)
        errors.extend(problems)
        for pid, p in found.items():
            if pid in taken:
                errors.append(f"{p.path}: user preset id '{pid}' is shadowed by a built-in preset")
                continue
            entries.append(Entry(p.id, p.name, p.family, p.source, False, str(p.path), *_modes(p)))
    _state["catalog"] = entries
    _state["errors"] = errors
    return entries


def _modes(preset):
    m = getattr(preset, "modes", None)
    return (tuple(m.lidar_modes), m.default_lidar_mode) if m else ((), None)


def catalog():
    """All presets (built-in first, then user), read once and cached."""
    if _state["catalog"] is None:
        refresh()
    return _state["catalog"]


def errors():
    """Problems found with user preset files at the last refresh."""
    return list(_state["errors"])


def entry(preset_id):
    """The catalog entry of ``preset_id`` or None."""
    for e in catalog():
        if e.id == preset_id:
            return e
    return None


def by_family():
    """[(Family, [entries])] in the registry's order (``FAMILIES``), empty families left
    out."""
    out = []
    for fam in FAMILIES:
        items = [e for e in catalog() if e.family == fam.id]
        if items:
            out.append((fam, items))
    return out


def family_label(family_id):
    """The UI's name of a device family (its id when it is no longer registered)."""
    return FAMILIES.label(family_id) if family_id in FAMILIES else family_id


def resolve(preset_id):
    """The validated ``DevicePreset`` for an id or name: shipped first, then user presets.
    A broken file among the user presets does not stop the others from resolving."""
    e = entry(preset_id)
    if e is not None and not e.builtin:
        return load_preset(e.path)
    try:
        return get_preset(preset_id)
    except PresetError:
        refresh()  # saved by another session or copied into the folder by hand
        e = entry(preset_id)
        if e is not None and not e.builtin:
            return load_preset(e.path)
        users = [x.id for x in catalog() if not x.builtin]
        broken = errors()
        unread = (f"; {len(broken)} user preset file(s) could not be read, the first: "
                  f"{broken[0]}") if broken else ""
        raise PresetError(
            f"unknown device preset '{preset_id}'; built-in: "
            f"{', '.join(x.id for x in catalog() if x.builtin)}; user presets in "
            f"{user_dir(create=False)}: {', '.join(users) or 'none'}{unread}") from None


def clear():
    _state["catalog"] = None
    _state["errors"] = []
