"""A unit's calibration file as a user preset (``rls presets import-calibration``).

The new preset is its base preset with the unit's angles (and beam origins, where the
file gives them) in place of the base's table: timing, range, noise, dropout, detection
and beam are the base's. It is stored as ``<user_dir>/<id>.toml`` with its angle table
``<user_dir>/tables/<id>.csv`` (whose ``# source:`` line names the file and its sha256).
"""

import math
import tempfile
from pathlib import Path

from . import schema as sch
from .angle_tables import ORIGIN_COLUMNS
from .calibration_files import FORMATS, read_calibration
from .families.spinning import channel_count, spinning_beam_origins
from .presets import get_preset, load_preset
from .user_presets import dumps_preset, preset_to_dict, refuse_builtin_id, user_folder
from ..errors import OutputError, PresetError
from ..output.io.atomic import atomic_write_bytes

# [scan] keys that say where the base's angles (and origins) came from: replaced
ANGLE_KEYS = ("table", "elevations_deg", "azimuth_offsets_deg", "table_source", "table_note",
              "channels", "upper_fov_deg", "lower_fov_deg", "azimuth_convention")
MAX_SOURCE = 4000


def check_base(base, cal, where):
    """The base must be a spinning preset of the file's vendor with as many channels."""
    if base.family != "spinning":
        raise PresetError(f"{where}: base preset '{base.id}' is a {base.family} device; a "
                          f"calibration file needs a spinning base of the same vendor")
    vendor = base.scan.get("azimuth_convention")
    if vendor != cal.vendor:
        raise PresetError(f"{where}: the file is a {FORMATS[cal.format]}, but base preset "
                          f"'{base.id}' is a {vendor or 'generic'} device; choose a "
                          f"{cal.vendor} base")
    want, got = channel_count(base.scan, base.table), len(cal.elevations_deg)
    if want != got:
        raise PresetError(f"{where}: the file has {got} channels, base preset '{base.id}' "
                          f"has {want}; choose the base of the same model")


def table_csv(cal, new_id):
    """The angle table text of ``cal`` (every value as read, degrees; origins metres)."""
    cols = ["channel", "elevation_deg", "azimuth_offset_deg"]
    if cal.origins_m is not None:
        cols += ORIGIN_COLUMNS
    out = [f"# source: {cal.file_name} (sha256 {cal.sha256}), {FORMATS[cal.format]}",
           f"# note: unit calibration imported by rls presets import-calibration as '{new_id}'; "
           f"{cal.note}".replace("\n", " "),
           ",".join(cols)]
    for i, (cid, el, az) in enumerate(zip(cal.channel_ids, cal.elevations_deg,
                                          cal.azimuth_offsets_deg)):
        row = [str(cid), repr(float(el)), repr(float(az))]
        if cal.origins_m is not None:
            row += [repr(float(v)) for v in cal.origins_m[i]]
        out.append(",".join(row))
    return "\n".join(out) + "\n"


def import_calibration(file, base, new_id, user_dir, name=None, overwrite=False):
    """Read the calibration ``file`` into a user preset ``new_id`` built on the preset
    ``base`` (id, name or DevicePreset); returns the stored preset."""
    where = str(file)
    if not isinstance(new_id, str) or not sch.ID_RE.match(new_id):
        raise PresetError(f"--id must be lower-case letters, digits, '_', '-' or '.' (at most "
                          f"64, starting with a letter or digit), got '{new_id}'")
    refuse_builtin_id(new_id, action="import")
    d = user_folder(user_dir)
    base_p = base if hasattr(base, "scan") else get_preset(base, user_dir)
    cal = read_calibration(file)
    check_base(base_p, cal, where)
    dest, table = d / f"{new_id}.toml", d / "tables" / f"{new_id}.csv"
    for f in (dest, table):
        if f.exists() and not overwrite:
            raise OutputError(f"{f}: already exists (choose another id or allow overwriting)")

    data = preset_to_dict(base_p)
    scan = {k: v for k, v in data["scan"].items() if k not in ANGLE_KEYS}
    if cal.origins_m is not None:
        scan.pop("beam_origins_m", None)  # the file's origins replace the base's
    elif "beam_origins_m" in scan and len(scan["beam_origins_m"]) != 1:
        scan.pop("beam_origins_m")  # per-channel origins of another unit
    times = getattr(base_p, "firing_times", None)
    if times is not None:  # the base's firing times, by channel id, in the file's row order
        missing = [c for c in cal.channel_ids if c not in times.by_channel]
        if missing:
            raise PresetError(f"{where}: channel {missing[0]} has no firing time in base "
                              f"preset '{base_p.id}' (its channels: "
                              f"{min(times.by_channel)}..{max(times.by_channel)})")
        zero = float(base_p.scan.get("firing_time_zero_us", 0.0))
        scan["firing_offsets_us"] = times.offsets_us(list(cal.channel_ids), zero)
    data["scan"] = {"table": f"tables/{new_id}.csv", "azimuth_convention": cal.vendor, **scan}
    data["id"] = new_id
    data["name"] = name or f"{base_p.name} ({Path(cal.file_name).stem})"
    what = "angles and beam origins" if cal.origins_m is not None else "angles"
    mine = (f"Unit calibration: {what} from {cal.file_name} (sha256 {cal.sha256}), a "
            f"{FORMATS[cal.format]}, imported with rls presets import-calibration into "
            f"tables/{new_id}.csv. Everything else as base preset '{base_p.id}': ")
    data["source"] = mine + base_p.source[:max(0, MAX_SOURCE - len(mine))]
    data.pop("fitted", None)
    data["fitted"] = False

    table_text = table_csv(cal, new_id).encode("utf-8")
    toml_text = dumps_preset(data)
    d.mkdir(parents=True, exist_ok=True)
    # Validate the pair before either is in place: the preset read back from a
    # temporary copy must load and build its pattern.
    try:
        with tempfile.TemporaryDirectory(prefix=f".{new_id}.import.", dir=d) as tmp:
            (Path(tmp) / "tables").mkdir()
            (Path(tmp) / "tables" / f"{new_id}.csv").write_bytes(table_text)
            (Path(tmp) / f"{new_id}.toml").write_text(toml_text, encoding="utf-8")
            check = load_preset(Path(tmp) / f"{new_id}.toml")
            _same_angles(check, cal)
            check.pattern()
    except OSError as exc:
        raise OutputError(f"{d}: cannot write the imported preset ({exc.strerror})") from None
    atomic_write_bytes(table, table_text, overwrite=True)
    atomic_write_bytes(dest, toml_text.encode("utf-8"), overwrite=True)
    return load_preset(dest)


def _same_angles(p, cal):
    """The stored table reads back as the file's values, bit for bit."""
    t = p.table
    ok = t.elevations_deg == tuple(map(float, cal.elevations_deg)) and \
        t.azimuth_offsets_deg == tuple(map(float, cal.azimuth_offsets_deg))
    if cal.origins_m is not None:
        got = spinning_beam_origins(p)
        ok = ok and all(math.isclose(a, b, rel_tol=0, abs_tol=0) for row, want in
                        zip(got.tolist(), cal.origins_m) for a, b in zip(row, want))
    if not ok:
        raise PresetError(f"{cal.file_name}: the stored table does not read back as the file")
