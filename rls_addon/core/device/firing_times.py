"""Per-channel firing times of a spinning device (vendor tables copied into
``presets/tables/*_firetimes.csv``).

A firing-time file is a small CSV like an angle table: ``#`` comment lines
(``# source:`` and ``# note:`` say where the numbers come from), the header
``channel,firetime_us``, then one row per channel with the vendor's channel id (the
ids of the preset's angle table, in any order) and its firing time in microseconds as
the vendor states it, relative to the vendor's own block reference time (Hesai: the
block's end for Pandar64/40P, negative times; the block's start for PandarQT/XT).

The preset says where that reference lies in RLS's firing cycle with
``firing_time_zero_us``: a channel fires ``firetime_us + firing_time_zero_us`` after the
start of its cycle, and must fire within the cycle.
"""

from dataclasses import dataclass
from pathlib import Path

from .csv_cells import commented_rows, finite_number
from ..errors import PresetError

MAX_FIRING_BYTES = 200_000
HEADER = ["channel", "firetime_us"]


@dataclass(frozen=True)
class FiringTimes:
    """Vendor firing times by channel id (microseconds, the vendor's reference)."""

    by_channel: dict
    source: str = ""
    note: str = ""
    name: str = ""

    def offsets_us(self, channel_ids, zero_us):
        """Firing offsets (us) within RLS's cycle for ``channel_ids`` (table order)."""
        return [self.by_channel[c] + zero_us for c in channel_ids]


def read_firing_times(path, channel_ids, where=None):
    """Read and validate a firing-time CSV against the angle table's ``channel_ids``:
    every channel of the table exactly once, nothing else. Errors name file and line."""
    path = Path(path)
    where = where or str(path)
    try:
        size = path.stat().st_size
        if size > MAX_FIRING_BYTES:
            raise PresetError(f"{where}: firing-time file is {size} bytes, more than "
                              f"{MAX_FIRING_BYTES}")
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise PresetError(f"{where}: cannot read firing-time file ({exc})") from None
    rows, source, note = commented_rows(text)
    header = None
    known = set(channel_ids)
    times, lines = {}, {}
    for lineno, line, cells in rows:
        if header is None:
            if cells != HEADER:
                raise PresetError(f"{where} line {lineno}: header must be "
                                  f"'{','.join(HEADER)}', got '{line}'")
            header = cells
            continue
        if len(cells) != 2:
            raise PresetError(f"{where} line {lineno}: expected 2 columns, got {len(cells)}")
        cid = finite_number(cells[0], where, lineno, "channel", PresetError)
        if cid != int(cid):
            raise PresetError(f"{where} line {lineno}: column 'channel' must be an integer, "
                              f"got '{cells[0]}'")
        cid = int(cid)
        if cid not in known:
            raise PresetError(f"{where} line {lineno}: channel {cid} is not in the preset's "
                              f"angle table")
        if cid in times:
            raise PresetError(f"{where} line {lineno}: channel {cid} given twice (first on "
                              f"line {lines[cid]})")
        t = finite_number(cells[1], where, lineno, "firetime_us", PresetError)
        if not -1e6 < t < 1e6:
            raise PresetError(f"{where} line {lineno}: column 'firetime_us' must be within "
                              f"+-1 s, got {t}")
        times[cid], lines[cid] = t, lineno
    if header is None:
        raise PresetError(f"{where}: firing-time file has no header '{','.join(HEADER)}'")
    missing = [c for c in channel_ids if c not in times]
    if missing:
        raise PresetError(f"{where}: no firing time for channel(s) "
                          f"{', '.join(map(str, missing[:8]))}"
                          f"{' ...' if len(missing) > 8 else ''} of the angle table")
    return FiringTimes(times, source, note, path.name)
