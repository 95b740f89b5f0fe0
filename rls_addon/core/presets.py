"""Device presets: validated data files (TOML), never code.

A preset file describes one device: identity and source, range model, dropout,
intensity attenuation and the scan pattern parameters of its family. ``load_preset``
validates a file and returns a ``DevicePreset``; every error names the file and key.
"""

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import PresetError
from .patterns.spinning import spinning_pattern, uniform_elevations_deg

FAMILIES = ("spinning", "mems", "risley", "custom")


@dataclass(frozen=True)
class RangeModel:
    min_m: float = 0.0
    max_m: float = 100.0
    noise_sigma_m: float = 0.0


@dataclass(frozen=True)
class DropoutModel:
    """CARLA-style dropout: a general rate, then intensity-dependent dropout below a limit."""

    general_rate: float = 0.0
    intensity_limit: float = 0.0
    intensity_zero: float = 0.0


@dataclass(frozen=True)
class DevicePreset:
    id: str
    name: str
    family: str
    source: str
    frequency_hz: float
    range: RangeModel = field(default_factory=RangeModel)
    dropout: DropoutModel = field(default_factory=DropoutModel)
    attenuation_per_m: float = 0.0
    scan: dict = field(default_factory=dict)
    path: str = ""

    def pattern(self):
        """The ``ScanPattern`` of one frame of this device."""
        s = self.scan
        if self.family == "spinning":
            if "elevations_deg" in s:
                el = s["elevations_deg"]
            else:
                el = uniform_elevations_deg(s["channels"], s["upper_fov_deg"], s["lower_fov_deg"])
            return spinning_pattern(el, self.frequency_hz, s["points_per_second"],
                                    s.get("azimuth_offsets_deg"))
        raise PresetError(f"{self.path or self.id}: family '{self.family}' has no pattern yet")


def _num(d, key, where, lo=None, hi=None, default=None):
    if key not in d:
        if default is not None:
            return float(default)
        raise PresetError(f"{where}: missing key '{key}' (expected a number)")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PresetError(f"{where}: key '{key}' must be a number, got {type(v).__name__}")
    v = float(v)
    if not math.isfinite(v):
        raise PresetError(f"{where}: key '{key}' must be finite, got {v}")
    if lo is not None and v < lo:
        raise PresetError(f"{where}: key '{key}' must be >= {lo}, got {v}")
    if hi is not None and v > hi:
        raise PresetError(f"{where}: key '{key}' must be <= {hi}, got {v}")
    return v


def _str(d, key, where):
    v = d.get(key)
    if not isinstance(v, str) or not v.strip():
        raise PresetError(f"{where}: key '{key}' must be a non-empty string")
    return v


def preset_from_dict(data, where="<preset>"):
    """Validate a parsed preset mapping and build a ``DevicePreset``."""
    if not isinstance(data, dict):
        raise PresetError(f"{where}: a preset must be a table of keys")
    family = _str(data, "family", where)
    if family not in FAMILIES:
        raise PresetError(f"{where}: key 'family' must be one of {', '.join(FAMILIES)}, got '{family}'")
    rng = data.get("range", {})
    rm = RangeModel(
        min_m=_num(rng, "min_m", f"{where} [range]", lo=0.0, hi=1e4, default=0.0),
        max_m=_num(rng, "max_m", f"{where} [range]", lo=0.01, hi=1e4),
        noise_sigma_m=_num(rng, "noise_sigma_m", f"{where} [range]", lo=0.0, hi=10.0, default=0.0),
    )
    if rm.min_m >= rm.max_m:
        raise PresetError(f"{where} [range]: 'min_m' ({rm.min_m}) must be below 'max_m' ({rm.max_m})")
    dr = data.get("dropout", {})
    dm = DropoutModel(
        general_rate=_num(dr, "general_rate", f"{where} [dropout]", 0.0, 1.0, default=0.0),
        intensity_limit=_num(dr, "intensity_limit", f"{where} [dropout]", 0.0, 1.0, default=0.0),
        intensity_zero=_num(dr, "intensity_zero", f"{where} [dropout]", 0.0, 1.0, default=0.0),
    )
    scan = data.get("scan", {})
    if not isinstance(scan, dict):
        raise PresetError(f"{where}: [scan] must be a table")
    return DevicePreset(
        id=_str(data, "id", where),
        name=_str(data, "name", where),
        family=family,
        source=_str(data, "source", where),
        frequency_hz=_num(data, "frequency_hz", where, lo=0.1, hi=1000.0),
        range=rm,
        dropout=dm,
        attenuation_per_m=_num(data, "attenuation_per_m", where, 0.0, 1.0, default=0.0),
        scan=dict(scan),
        path=where,
    )


def load_preset(path):
    """Read and validate one preset file."""
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise PresetError(f"{p}: preset file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise PresetError(f"{p}: not valid TOML ({exc})") from None
    return preset_from_dict(data, str(p))


def builtin_presets_dir():
    """The directory of the shipped presets: inside the installed extension, or the
    repository's top-level ``presets/`` when run from a checkout."""
    here = Path(__file__).resolve().parent.parent
    for cand in (here / "presets", here.parent / "presets"):
        if cand.is_dir():
            return cand
    raise PresetError(f"no presets directory found next to {here}")


def builtin_presets():
    """All shipped presets by id, sorted by id."""
    out = {}
    for f in sorted(builtin_presets_dir().glob("*.toml")):
        p = load_preset(f)
        out[p.id] = p
    return out


def get_preset(name):
    """Look a shipped preset up by id or display name (case-insensitive)."""
    presets = builtin_presets()
    key = name.strip().lower()
    for p in presets.values():
        if key in (p.id.lower(), p.name.lower()):
            return p
    raise PresetError(f"unknown device preset '{name}'; known: {', '.join(presets)}")
