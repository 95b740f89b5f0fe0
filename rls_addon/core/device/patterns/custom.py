"""User scan-pattern files: a CSV of ``time_s,azimuth_deg,elevation_deg[,channel]``.

One row per ray in firing order; ``#`` lines and blank lines are skipped; a header row
naming the columns is optional. Azimuth is counter-clockwise from +X (our convention,
the same as ``rls pattern`` writes), elevation up from the XY plane, time in seconds
since the frame start, non-decreasing. Errors name the file and line.
"""

from pathlib import Path

import numpy as np

from ..csv_cells import finite_number
from ...errors import PatternError
from .base import ScanPattern, directions_from_angles

MAX_RAYS = 10_000_000
MAX_FILE_BYTES = 1_000_000_000
COLUMNS = ("time_s", "azimuth_deg", "elevation_deg", "channel")


def _row(cells, where, lineno):
    vals = []
    for name, text in zip(COLUMNS, cells):
        vals.append(finite_number(text, where, lineno, name, PatternError))
    t, az, el = vals[:3]
    if t < 0:
        raise PatternError(f"{where} line {lineno}: 'time_s' must be >= 0, got {t}")
    if not -90.0 <= el <= 90.0:
        raise PatternError(f"{where} line {lineno}: 'elevation_deg' must be in -90..90, got {el}")
    if not -720.0 <= az <= 720.0:
        raise PatternError(f"{where} line {lineno}: 'azimuth_deg' must be in -720..720, got {az}")
    ch = vals[3] if len(vals) > 3 else 0.0
    if ch != int(ch) or not 0 <= ch < 65536:
        raise PatternError(f"{where} line {lineno}: 'channel' must be an integer 0..65535, got {ch}")
    return t, az, el, ch


def read_pattern_csv(path, frequency_hz=None, where=None):
    """Load a scan-pattern CSV as one frame.

    The frame period is ``1 / frequency_hz`` when given (every time must then be below
    it), else the last time plus the median step (the file is one frame)."""
    path = Path(path)
    where = where or str(path)
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise PatternError(f"{where}: pattern file is larger than {MAX_FILE_BYTES} bytes")
        fh = open(path, encoding="utf-8")
    except FileNotFoundError:
        raise PatternError(f"{where}: pattern file not found") from None
    except OSError as exc:
        raise PatternError(f"{where}: cannot read pattern file ({exc.strerror})") from None
    rows = []
    ncols = None
    with fh:
        try:
            for lineno, raw in enumerate(fh, start=1):
                line = raw.strip()
                if not line or line.startswith("#"):
                    continue
                cells = [c.strip() for c in line.split(",")]
                if ncols is None and cells[0].lower() in ("time_s", "time"):
                    names = tuple(c.lower() for c in cells)
                    if names not in (COLUMNS[:3], COLUMNS):
                        raise PatternError(f"{where} line {lineno}: header must be "
                                           f"'time_s,azimuth_deg,elevation_deg[,channel]'")
                    ncols = len(names)
                    continue
                if ncols is None:
                    ncols = len(cells)
                    if ncols not in (3, 4):
                        raise PatternError(f"{where} line {lineno}: expected 3 or 4 columns "
                                           f"(time_s,azimuth_deg,elevation_deg[,channel]), got {ncols}")
                if len(cells) != ncols:
                    raise PatternError(f"{where} line {lineno}: expected {ncols} columns, got {len(cells)}")
                rows.append(_row(cells, where, lineno))
                if rows[-1][0] < rows[-2 if len(rows) > 1 else -1][0]:
                    raise PatternError(f"{where} line {lineno}: 'time_s' must be non-decreasing "
                                       f"(rays in firing order)")
                if len(rows) > MAX_RAYS:
                    raise PatternError(f"{where}: more than {MAX_RAYS} rays")
        except UnicodeDecodeError:
            raise PatternError(f"{where}: pattern file is not UTF-8 text") from None
    if not rows:
        raise PatternError(f"{where}: pattern file has no rays")
    a = np.array(rows, dtype=np.float64)
    t = a[:, 0]
    if frequency_hz is not None:
        period = 1.0 / float(frequency_hz)
        if t[-1] >= period:
            raise PatternError(f"{where}: time {t[-1]} s is not below the frame period {period} s "
                               f"(frequency {frequency_hz} Hz)")
    else:
        steps = np.diff(t)
        step = float(np.median(steps)) if steps.size else 0.0
        period = float(t[-1] + max(step, 1e-6))
    d = directions_from_angles(np.deg2rad(a[:, 1]), np.deg2rad(a[:, 2]))
    return ScanPattern(d, t, a[:, 3].astype(np.uint16), period)


def write_pattern_csv(path_or_file, times, azimuth_deg, elevation_deg, channels):
    """Write rays as ``time_s,azimuth_deg,elevation_deg,channel`` (the format read above)."""
    a = np.column_stack([times, azimuth_deg, elevation_deg])
    header = ",".join(COLUMNS)
    own = isinstance(path_or_file, (str, Path))
    fh = open(path_or_file, "w", encoding="utf-8", newline="\n") if own else path_or_file
    try:
        fh.write(header + "\n")
        body = np.column_stack([a, np.asarray(channels, dtype=np.float64)])
        np.savetxt(fh, body, fmt=["%.9f", "%.6f", "%.6f", "%d"], delimiter=",")
    finally:
        if own:
            fh.close()
