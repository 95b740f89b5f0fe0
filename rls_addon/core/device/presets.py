"""Device presets: validated data files (TOML), never code.

A preset file describes one device: identity and source, range model, dropout,
intensity attenuation and the scan pattern parameters of its family. ``load_preset``
validates a file and returns a ``DevicePreset``; every error names the file and key.
The file format is described in docs/presets.md; the ``[scan]`` table of each family is
checked, and its pattern built, by the family's module (``families``).
"""

import math
import tomllib
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import schema as sch
from .angle_tables import AngleTable
from .families import FAMILIES, family_of
# scan/session.py reads a spinning preset's channel elevations from here
from .families.spinning import spinning_elevations_offsets  # noqa: F401
from .modes import check_modes
from ..physics.detection import DetectionModel
from ..errors import PatternError, PresetError
from .patterns.base import ScanPattern

SCHEMA_VERSION = 1
MAX_PRESET_BYTES = 2_000_000
TOP_KEYS = {"schema", "id", "name", "family", "source", "fitted", "frequency_hz", "range",
            "dropout", "attenuation_per_m", "detection", "beam", "scan", "modes"}
PATTERN_CACHE_FRAMES = 4


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


@dataclass(frozen=True, eq=False)
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
    fitted: bool = False          # True when scan parameters were fitted, not published
    table: AngleTable = None      # the resolved angle table of a spinning preset, if any
    base_dir: str = ""            # folder that relative file names in [scan] resolve against
    rays_per_frame: int = None    # estimated at validation (None for custom files)
    # Detection by the LiDAR equation from the datasheet's range-at-reflectivity figures
    # ([detection]); None: CARLA's model (every hit within range returns)
    detection: DetectionModel = None
    # The beam's divergence, return mode and echo separation ([beam], footprint.Beam);
    # None: a thin ray with one return
    beam: object = None
    # Per-channel vendor firing times of a spinning preset ([scan] firing_times,
    # firing_times.FiringTimes), or None
    firing_times: object = None
    # The modes the device offers ([modes], modes.Modes), or None: only this one
    modes: object = None

    @property
    def period(self):
        return 1.0 / self.frequency_hz

    def __getstate__(self):
        """Pickled (sent to a worker) without its cached patterns."""
        return {k: v for k, v in self.__dict__.items() if k != "_pattern_cache"}

    def __setstate__(self, state):
        self.__dict__.update(state)

    def pattern(self, frame=0):
        """The ``ScanPattern`` of one frame (``frame`` matters for the non-repeating
        families: Risley prisms and MEMS mirrors keep moving between frames). Results
        are cached per preset object and read-only; calling again is cheap."""
        cache = self.__dict__.setdefault("_pattern_cache", OrderedDict())
        family = family_of(self)
        key = int(frame) if family.changes_per_frame else 0
        if key in cache:
            cache.move_to_end(key)
            return cache[key]
        pat = family.build(self, key)
        for a in (pat.directions, pat.times, pat.channels, pat.origins):
            if a is not None:
                a.setflags(write=False)
        cache[key] = pat
        while len(cache) > PATTERN_CACHE_FRAMES:
            cache.popitem(last=False)
        return pat


# ---- validation -------------------------------------------------------------------------

def preset_from_dict(data, where="<preset>", base_dir=None):
    """Validate a parsed preset mapping and build a ``DevicePreset``.

    ``base_dir`` is the folder relative file names (angle tables, pattern files) resolve
    against; it defaults to the folder of ``where`` when that names an existing file."""
    if not isinstance(data, dict):
        raise PresetError(f"{where}: a preset must be a table of keys")
    if base_dir is None and where and Path(where).is_file():
        base_dir = Path(where).parent
    sch.no_unknown(data, TOP_KEYS, where)
    if "schema" in data:
        sch.integer(data, "schema", where, SCHEMA_VERSION, SCHEMA_VERSION)
    pid = sch.string(data, "id", where, max_len=64)
    if not sch.ID_RE.match(pid):
        raise PresetError(f"{where}: key 'id' must be lower-case letters, digits, '_', '-' or '.' "
                          f"(at most 64, starting with a letter or digit), got '{pid}'")
    name = sch.string(data, "name", where, max_len=200)
    family = sch.choice(data, "family", where, FAMILIES.ids)
    source = sch.string(data, "source", where, max_len=4000)
    fitted = data.get("fitted", False)
    if not isinstance(fitted, bool):
        raise PresetError(f"{where}: key 'fitted' must be true or false")
    freq = sch.num(data, "frequency_hz", where, lo=0.1, hi=1000.0)

    rw = f"{where} [range]"
    rng = sch.table_of(data, "range", where)
    sch.no_unknown(rng, {"min_m", "max_m", "noise_sigma_m"}, rw)
    rm = RangeModel(
        min_m=sch.num(rng, "min_m", rw, lo=0.0, hi=1e4, default=0.0),
        max_m=sch.num(rng, "max_m", rw, lo=0.01, hi=1e4),
        noise_sigma_m=sch.num(rng, "noise_sigma_m", rw, lo=0.0, hi=10.0, default=0.0),
    )
    if rm.min_m >= rm.max_m:
        raise PresetError(f"{rw}: 'min_m' ({rm.min_m}) must be below 'max_m' ({rm.max_m})")
    dw = f"{where} [dropout]"
    dr = sch.table_of(data, "dropout", where)
    sch.no_unknown(dr, {"general_rate", "intensity_limit", "intensity_zero"}, dw)
    dm = DropoutModel(
        general_rate=sch.num(dr, "general_rate", dw, 0.0, 1.0, default=0.0),
        intensity_limit=sch.num(dr, "intensity_limit", dw, 0.0, 1.0, default=0.0),
        intensity_zero=sch.num(dr, "intensity_zero", dw, 0.0, 1.0, default=0.0),
    )
    detection = sch.check_detection(data["detection"], f"{where} [detection]") \
        if "detection" in data else None
    beam = sch.check_beam(data["beam"], f"{where} [beam]") if "beam" in data else None
    if "scan" not in data:
        raise PresetError(f"{where}: missing table [scan] (the scan pattern parameters)")
    scan = sch.table_of(data, "scan", where)
    sw = f"{where} [scan]"
    fam = FAMILIES.get(family)
    sch.no_unknown(scan, fam.scan_keys, sw)
    rays, resolved = fam.check(scan, sw, freq, base_dir)
    modes = check_modes(data["modes"], f"{where} [modes]", family, freq, scan, beam) \
        if "modes" in data else None
    return DevicePreset(
        id=pid, name=name, family=family, source=source, frequency_hz=freq, range=rm, dropout=dm,
        attenuation_per_m=sch.num(data, "attenuation_per_m", where, 0.0, 1.0, default=0.0),
        scan=dict(scan), path=where, fitted=fitted,
        base_dir="" if base_dir is None else str(base_dir), rays_per_frame=rays,
        detection=detection, beam=beam, modes=modes, **resolved,
    )


_LOAD_CACHE = {}
# a family added or removed changes what a file validates to
FAMILIES.subscribe(lambda families: _LOAD_CACHE.clear())


def load_preset(path):
    """Read and validate one preset file (TOML only; nothing in it is executed).
    Results are cached per (path, modification time, size)."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise PresetError(f"{p}: preset file not found") from None
    except OSError as exc:
        raise PresetError(f"{p}: cannot read preset file ({exc.strerror})") from None
    if not p.is_file():
        raise PresetError(f"{p}: not a preset file")
    if st.st_size > MAX_PRESET_BYTES:
        raise PresetError(f"{p}: preset file is {st.st_size} bytes, more than {MAX_PRESET_BYTES}")
    key = (str(p.resolve()), st.st_mtime_ns, st.st_size)
    if key in _LOAD_CACHE:
        return _LOAD_CACHE[key]
    try:
        with open(p, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise PresetError(f"{p}: not valid TOML ({exc})") from None
    except UnicodeDecodeError:
        raise PresetError(f"{p}: not UTF-8 text") from None
    except RecursionError:
        raise PresetError(f"{p}: TOML nested too deeply") from None
    except ValueError as exc:  # a value tomllib cannot convert (an integer of 5000 digits)
        raise PresetError(f"{p}: not a readable TOML file ({str(exc).split(';')[0]})") from None
    preset = preset_from_dict(data, str(p), base_dir=p.parent)
    if len(_LOAD_CACHE) > 256:
        _LOAD_CACHE.clear()
    _LOAD_CACHE[key] = preset
    return preset


def builtin_presets_dir():
    """The directory of the shipped presets: inside the installed extension, or the
    repository's top-level ``presets/`` when run from a checkout."""
    here = Path(__file__).resolve().parents[2]  # rls_addon/ (core/device/presets.py)
    for cand in (here / "presets", here.parent / "presets"):
        if cand.is_dir():
            return cand
    raise PresetError(f"no presets directory found next to {here}")


def presets_in(directory):
    """All presets (``*.toml``) in one folder by id, sorted by id; a duplicate id is an error."""
    out, problems = readable_presets_in(directory)
    if problems:
        raise PresetError(problems[0])
    return out


def readable_presets_in(directory):
    """``(presets by id, problems)``: every preset of one folder that validates, and one
    message per file that does not (or whose id another file already uses), so one broken
    file neither hides the others nor goes unreported."""
    out, problems = {}, []
    for f in sorted(Path(directory).glob("*.toml")):
        try:
            p = load_preset(f)
        except PresetError as exc:
            problems.append(str(exc))
            continue
        if p.id in out:
            problems.append(f"{f}: id '{p.id}' already used by {out[p.id].path}")
            continue
        out[p.id] = p
    return dict(sorted(out.items())), problems


def builtin_presets():
    """All shipped presets by id, sorted by id."""
    return presets_in(builtin_presets_dir())


def get_preset(name, user_dir=None):
    """Look a preset up by id or display name (case-insensitive): the shipped presets,
    then those in ``user_dir`` if given. A path to a ``.toml`` file is loaded directly."""
    if not isinstance(name, str) or not name.strip():
        raise PresetError("a preset name is required")
    if name.endswith(".toml") and Path(name).is_file():
        return load_preset(name)
    presets = dict(builtin_presets())
    problems = []  # the user folder's files that did not load: they hide no other preset
    if user_dir is not None and Path(user_dir).is_dir():
        users, problems = readable_presets_in(user_dir)
        for pid, p in users.items():
            presets.setdefault(pid, p)
    found = _lookup(presets, name)
    if found is not None:
        # a user preset whose id another file of the folder uses too: which one is
        # meant cannot be told, so neither is taken
        clash = [m for m in problems if f"id '{found.id}' already used by" in m]
        if clash:
            raise PresetError(clash[0])
        return found
    broken = f"; user presets that did not load: {'; '.join(problems)}" if problems else ""
    raise PresetError(f"unknown device preset '{name}'; known: {', '.join(presets)}{broken}")


def _lookup(presets, name):
    """The preset of ``presets`` named ``name`` by id or display name (case-insensitive,
    then ignoring all but letters and digits: 'vlp-16', 'VLP16', 'pandar 64'), or None."""
    key = name.strip().lower()
    for p in presets.values():
        if key in (p.id.lower(), p.name.lower()):
            return p
    norm = _alnum(key)
    for p in presets.values():
        if norm and norm in (_alnum(p.id), _alnum(p.name), _alnum(p.name.partition(" ")[2])):
            return p
    return None


def _alnum(text):
    return "".join(ch for ch in text.lower() if ch.isalnum())


def pattern_span(preset, duration_s):
    """Rays of ``duration_s`` seconds as (times, directions, channels), frames back to back
    with times continuing across frames (frame k starts at k * period)."""
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
        raise PatternError(f"duration must be a positive number of seconds, got {duration_s}")
    frames = int(math.ceil(duration_s * preset.frequency_hz - 1e-9))
    if frames * (preset.rays_per_frame or 1) > 50_000_000 or frames > 100_000:
        raise PatternError(f"{duration_s} s of '{preset.id}' is too many rays; use a shorter duration")
    ts, ds, cs = [], [], []
    for k in range(frames):
        pat = preset.pattern(k)
        t = pat.times + k * preset.period
        keep = t < duration_s
        ts.append(t[keep])
        ds.append(pat.directions[keep])
        cs.append(pat.channels[keep])
    return np.concatenate(ts), np.concatenate(ds), np.concatenate(cs)


__all__ = [
    "RangeModel", "DropoutModel", "DevicePreset", "ScanPattern", "preset_from_dict",
    "load_preset", "builtin_presets_dir", "builtin_presets", "presets_in", "readable_presets_in",
    "get_preset", "pattern_span",
]
