"""The custom family: a pattern read from a CSV file of rays (``time_s, azimuth_deg,
elevation_deg[, channel]``, what ``rls pattern`` writes; ``patterns.custom``), named by
``[scan] file`` relative to the preset and confined to its folder."""

from .. import schema as sch
from ..angle_tables import resolve_table_path
from ..patterns.custom import read_pattern_csv
from ...errors import PatternError, PresetError

SCAN_KEYS = frozenset({"file"})


def check(scan, where, frequency_hz, base_dir):
    """Validate a custom ``[scan]``: ``(None, {})`` (its rays are counted once read)."""
    sch.string(scan, "file", where)
    if base_dir is None:
        raise PresetError(f"{where}: key 'file' needs a preset file to resolve it against")
    _resolve(scan["file"], base_dir, where)
    return None, {}


def _resolve(name, base_dir, where):
    """The file ``name`` resolved as angle tables are (``resolve_table_path``)."""
    try:
        return resolve_table_path(name, base_dir, where)
    except PresetError as exc:
        raise PresetError(str(exc).replace("key 'table'", "key 'file'")) from None


def custom_pattern_path(preset):
    """The resolved pattern CSV of a custom-family preset."""
    if not preset.base_dir:
        raise PresetError(f"{preset.path or preset.id} [scan]: key 'file' needs a preset file "
                          f"to resolve it against")
    return _resolve(preset.scan["file"], preset.base_dir, f"{preset.path} [scan]")


def build(p, frame):
    """The ``ScanPattern`` of a custom preset: its file's rays (the same every frame)."""
    path = custom_pattern_path(p)
    try:
        return read_pattern_csv(path, p.frequency_hz)
    except PatternError as exc:
        raise PatternError(f"{p.path or p.id} [scan] file: {exc}") from None
