"""Per-channel angle tables (vendor calibration files copied into ``presets/tables``).

A table is a small CSV: ``#`` comment lines (``# source:`` and ``# note:`` say where the
numbers come from), a header ``channel,elevation_deg[,azimuth_offset_deg[,origin_x_m,
origin_y_m,origin_z_m]]``, then one row per channel in the vendor's order. Offsets are
stored exactly as the vendor gives them; ``AZIMUTH_CONVENTIONS`` converts them to our frame
(azimuth counter-clockwise from +X). The optional origin columns are where each beam
leaves from, in metres, in the head frame (the frame that turns with the head: +X the
head's forward direction, +Y left, +Z up); absent, every beam leaves from the sensor origin.
"""

from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from .csv_cells import commented_rows, finite_number
from ..errors import PresetError

MAX_TABLE_BYTES = 1_000_000
MAX_TABLE_ROWS = 1024
MAX_ORIGIN_M = 1.0  # a beam origin further than this from the sensor origin is an error
ORIGIN_COLUMNS = ["origin_x_m", "origin_y_m", "origin_z_m"]

# Sign that turns a vendor azimuth offset into our counter-clockwise offset (degrees).
#   hesai:     azimuth = block_azimuth + offset, measured clockwise (x = d cos(el) sin(az),
#              y = d cos(el) cos(az) with y forward) -> ours = -offset
#   velodyne:  azimuth = encoder - rot_correction, clockwise -> ours = +rot_correction
#   ouster:    theta = encoder - beam_azimuth, already counter-clockwise -> ours = -beam_azimuth
#   robosense: azimuth = block_azimuth + offset, clockwise -> ours = -offset
#   ccw:       offsets already in our convention
AZIMUTH_CONVENTIONS = {"hesai": -1.0, "velodyne": 1.0, "ouster": -1.0, "robosense": -1.0, "ccw": 1.0}


@dataclass(frozen=True)
class AngleTable:
    """Rows in file order. ``azimuth_offsets_deg`` are the vendor's raw values."""

    channel_ids: tuple
    elevations_deg: tuple
    azimuth_offsets_deg: tuple
    source: str = ""
    note: str = ""
    name: str = ""
    origins_m: tuple = None  # ((x, y, z) per row, head frame, metres) or None


def resolve_table_path(rel, base_dir, where):
    """Resolve a table file name relative to ``base_dir``, confined to that directory.

    Rejects absolute paths, drive letters, backslashes and ``..`` so a preset cannot
    reach outside its own folder; the file must exist and be a regular file."""
    if not isinstance(rel, str) or not rel.strip():
        raise PresetError(f"{where}: key 'table' must be a relative file name like 'tables/x.csv'")
    if "\\" in rel or ":" in rel or rel.startswith("/") or rel.startswith("~"):
        raise PresetError(f"{where}: key 'table' must be a relative path inside the presets "
                          f"folder, got '{rel}'")
    parts = PurePosixPath(rel).parts
    if any(p in ("..", "") for p in parts):
        raise PresetError(f"{where}: key 'table' must not contain '..', got '{rel}'")
    base = Path(base_dir).resolve()
    path = (base / rel).resolve()
    if base != path and base not in path.parents:
        raise PresetError(f"{where}: key 'table' points outside the presets folder: '{rel}'")
    if not path.is_file():
        raise PresetError(f"{where}: key 'table': file '{rel}' not found next to the preset")
    return path


def _fnum(text, where, line, col):
    return finite_number(text, where, line, col, PresetError)


def read_angle_table(path, where=None):
    """Read and validate an angle table CSV. Errors name the file and line."""
    path = Path(path)
    where = where or str(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise PresetError(f"{where}: cannot read angle table ({exc.strerror})") from None
    if size > MAX_TABLE_BYTES:
        raise PresetError(f"{where}: angle table is {size} bytes, more than {MAX_TABLE_BYTES}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise PresetError(f"{where}: cannot read angle table ({exc})") from None
    rows, source, note = commented_rows(text)
    header = None
    ids, els, azs, origins = [], [], [], []
    for lineno, line, cells in rows:
        if header is None:
            header = cells
            if header[:2] != ["channel", "elevation_deg"] or \
                    header[2:] not in ([], ["azimuth_offset_deg"],
                                       ["azimuth_offset_deg"] + ORIGIN_COLUMNS):
                raise PresetError(f"{where} line {lineno}: header must be 'channel,elevation_deg"
                                  f"[,azimuth_offset_deg[,{','.join(ORIGIN_COLUMNS)}]]', "
                                  f"got '{line}'")
            continue
        if len(cells) != len(header):
            raise PresetError(f"{where} line {lineno}: expected {len(header)} columns, got {len(cells)}")
        cid = _fnum(cells[0], where, lineno, "channel")
        if cid != int(cid) or not 0 <= cid < 65536:
            raise PresetError(f"{where} line {lineno}: column 'channel' must be an integer 0..65535")
        el = _fnum(cells[1], where, lineno, "elevation_deg")
        if not -90.0 <= el <= 90.0:
            raise PresetError(f"{where} line {lineno}: column 'elevation_deg' must be in -90..90, got {el}")
        az = _fnum(cells[2], where, lineno, "azimuth_offset_deg") if len(cells) > 2 else 0.0
        if not -360.0 <= az <= 360.0:
            raise PresetError(f"{where} line {lineno}: column 'azimuth_offset_deg' must be in "
                              f"-360..360, got {az}")
        if len(cells) > 3:
            xyz = tuple(_fnum(c, where, lineno, name) for c, name in zip(cells[3:], ORIGIN_COLUMNS))
            for v, name in zip(xyz, ORIGIN_COLUMNS):
                if abs(v) > MAX_ORIGIN_M:
                    raise PresetError(f"{where} line {lineno}: column '{name}' must be in "
                                      f"-{MAX_ORIGIN_M:g}..{MAX_ORIGIN_M:g} m, got {v}")
            origins.append(xyz)
        ids.append(int(cid))
        els.append(el)
        azs.append(az)
        if len(ids) > MAX_TABLE_ROWS:
            raise PresetError(f"{where}: angle table has more than {MAX_TABLE_ROWS} rows")
    if not ids:
        raise PresetError(f"{where}: angle table has no rows")
    return AngleTable(tuple(ids), tuple(els), tuple(azs), source, note, path.name,
                      tuple(origins) if origins else None)


def ccw_offsets_deg(table_offsets_deg, convention):
    """Vendor azimuth offsets (degrees) in our counter-clockwise convention."""
    return AZIMUTH_CONVENTIONS[convention] * np.asarray(table_offsets_deg, dtype=np.float64)
