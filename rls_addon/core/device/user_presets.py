"""User presets: save, import and export preset files in a user folder.

The folder is passed in (the Blender layer supplies ``bpy.utils.extension_path_user``).
Saved and exported files are self-contained: angle tables are inlined as lists, so a
shared file works on another machine; the only file reference left is the pattern CSV of
a custom-family preset, which is copied next to the preset under a relative name.
"""

import json
import math
import shutil
from pathlib import Path

from ..errors import OutputError, PresetError
from .families.custom import custom_pattern_path
from .presets import builtin_presets, load_preset, presets_in

TOP_ORDER = ("schema", "id", "name", "family", "source", "fitted", "frequency_hz", "attenuation_per_m")


def preset_to_dict(preset):
    """A plain mapping of ``preset`` in file form, angle tables inlined (vendor values
    and convention unchanged, the table's source and note kept as ``table_source``/``table_note``)."""
    scan = dict(preset.scan)
    if "table" in scan and preset.table is not None:
        del scan["table"]
        scan["elevations_deg"] = list(preset.table.elevations_deg)
        scan["azimuth_offsets_deg"] = list(preset.table.azimuth_offsets_deg)
        if preset.table.origins_m is not None:
            scan["beam_origins_m"] = [list(o) for o in preset.table.origins_m]
        scan["table_source"] = preset.table.source or preset.table.name
        if preset.table.note:
            scan["table_note"] = preset.table.note
    if "firing_times" in scan and getattr(preset, "firing_times", None) is not None:
        # inlined as offsets within the cycle, in the table's order
        zero = float(scan.pop("firing_time_zero_us", 0.0))
        del scan["firing_times"]
        scan["firing_offsets_us"] = preset.firing_times.offsets_us(preset.table.channel_ids, zero)
    out = {
        "schema": 1, "id": preset.id, "name": preset.name, "family": preset.family,
        "source": preset.source, "fitted": preset.fitted, "frequency_hz": preset.frequency_hz,
        "attenuation_per_m": preset.attenuation_per_m,
        "range": {"min_m": preset.range.min_m, "max_m": preset.range.max_m,
                  "noise_sigma_m": preset.range.noise_sigma_m},
        "dropout": {"general_rate": preset.dropout.general_rate,
                    "intensity_limit": preset.dropout.intensity_limit,
                    "intensity_zero": preset.dropout.intensity_zero},
    }
    det = preset.detection
    if det is not None:
        out["detection"] = {"range_at_reflectivity": [list(f) for f in det.figures],
                            "probability_at_range": det.probability,
                            "intensity": det.intensity, "logistic_width": det.width}
    beam = getattr(preset, "beam", None)
    if beam is not None:
        h, v = beam.divergence_rad
        out["beam"] = {"divergence_rad": h if h == v else [h, v],
                       "return_mode": beam.return_mode,
                       "echo_separation_m": beam.echo_separation_m}
    modes = getattr(preset, "modes", None)
    if modes is not None:
        out["modes"] = {k: v for k, v in modes.to_dict().items() if not k.startswith("default_")}
    out["scan"] = scan
    return out


def _value(v, where):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise PresetError(f"{where}: cannot write a non-finite number")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # JSON string escapes are valid TOML basic-string escapes
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, where) for x in v) + "]"
    raise PresetError(f"{where}: cannot write a value of type {type(v).__name__}")


def dumps_preset(data):
    """TOML text for a preset mapping (top-level scalars, then one level of tables)."""
    keys = [k for k in TOP_ORDER if k in data] + [k for k in data if k not in TOP_ORDER]
    lines = []
    tables = []
    for k in keys:
        if isinstance(data[k], dict):
            tables.append(k)
        else:
            lines.append(f"{k} = {_value(data[k], k)}")
    for t in tables:
        lines += ["", f"[{t}]"]
        for k, v in data[t].items():
            if isinstance(v, dict):
                raise PresetError(f"[{t}]: nested table '{k}' is not part of the preset format")
            lines.append(f"{k} = {_value(v, f'[{t}] {k}')}")
    return "\n".join(lines) + "\n"


def _write_preset(preset, dest, pattern_name, overwrite):
    dest = Path(dest)
    if dest.exists() and not overwrite:
        raise OutputError(f"{dest}: already exists (choose another name or allow overwriting)")
    data = preset_to_dict(preset)
    if preset.family == "custom":
        src = custom_pattern_path(preset)
        target = dest.parent / pattern_name
        if target.resolve() != src.resolve():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, target)
        data["scan"]["file"] = Path(pattern_name).as_posix()
    text = dumps_preset(data)
    tmp = dest.with_name(dest.name + ".tmp")
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text, encoding="utf-8")
        load_preset(tmp)  # never write a file we could not read back
        tmp.replace(dest)
    except OSError as exc:
        raise OutputError(f"{dest}: cannot write preset ({exc.strerror})") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return dest


def refuse_builtin_id(preset_id, where="", action="save"):
    """The one rule between user and built-in presets: a user preset never takes a
    built-in preset's id (it would shadow it), and built-in presets are read-only."""
    if preset_id in builtin_presets():
        prefix = f"{where}: key 'id': " if where else ""
        if action == "delete":
            raise PresetError(f"'{preset_id}' is a built-in preset and read-only; only user "
                              "presets can be deleted")
        raise PresetError(f"{prefix}'{preset_id}' is a built-in preset id; give the "
                          f"{'imported ' if action == 'import' else ''}preset another id")


def user_folder(user_dir):
    """``user_dir`` as a Path, refused when it names something other than a folder
    (made when missing): writing into a file said only 'File exists'."""
    d = Path(user_dir)
    if d.exists() and not d.is_dir():
        raise OutputError(f"{d}: not a folder; give --user-dir the folder of your user "
                          "presets (it is made when missing)")
    return d


def save_user_preset(preset, user_dir, overwrite=False):
    """Store ``preset`` as ``<user_dir>/<id>.toml`` (self-contained). Returns the path.
    A built-in preset's id is refused."""
    refuse_builtin_id(preset.id)
    d = user_folder(user_dir)
    return _write_preset(preset, d / f"{preset.id}.toml", f"patterns/{preset.id}.csv", overwrite)


def import_preset(src, user_dir, overwrite=False):
    """Validate the preset file ``src`` and store it in ``user_dir``; returns the stored
    preset. A file whose id is a built-in preset's is refused."""
    p = load_preset(src)
    refuse_builtin_id(p.id, where=str(src), action="import")
    return load_preset(save_user_preset(p, user_dir, overwrite))


def export_preset(preset, dest, overwrite=False):
    """Write ``preset`` to ``dest`` as a file to share (tables inlined, no absolute paths;
    a custom pattern CSV goes next to it as ``<stem>.pattern.csv``)."""
    dest = Path(dest)
    if dest.suffix != ".toml":
        raise OutputError(f"{dest}: a preset file must end in .toml")
    return _write_preset(preset, dest, f"{dest.stem}.pattern.csv", overwrite)


def user_presets(user_dir):
    """Presets stored in ``user_dir`` by id (empty if the folder does not exist)."""
    d = Path(user_dir)
    return presets_in(d) if d.is_dir() else {}


def delete_user_preset(preset_id, user_dir):
    """Remove ``<user_dir>/<id>.toml`` (and its copied pattern CSV, if any); built-in
    presets are read-only."""
    refuse_builtin_id(preset_id, action="delete")
    d = Path(user_dir)
    p = user_presets(d).get(preset_id)
    if p is None:
        raise PresetError(f"no user preset '{preset_id}' in {d}")
    if p.family == "custom":
        csv = d / "patterns" / f"{preset_id}.csv"
        if csv.is_file():
            csv.unlink()
    if p.scan.get("table") == f"tables/{preset_id}.csv":  # an imported calibration's table
        table = d / "tables" / f"{preset_id}.csv"
        if table.is_file():
            table.unlink()
    Path(p.path).unlink()
