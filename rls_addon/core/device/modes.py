"""The modes a spinning device offers (a preset's ``[modes]`` table) and a preset as one
unit runs them: its lidar mode (Ouster's columns x rate), its rotation rate (a nominal
mode or a unit's measured rate) and its return mode.

``[modes]`` keys (all optional; each is a list of what the device can be set to, the
vendor's default being what the rest of the preset describes):

    rotation_hz        nominal rotation rates (Hz) the device can be set to, e.g. [10, 20];
                       a measured rate is accepted within ROTATION_TOLERANCE of one
    rotation_range_hz  [lowest, highest]: any rate in between (Velodyne's 300-1200 rpm)
    lidar_mode         Ouster's "<columns>x<rate>" modes, e.g. ["512x10", "1024x10"]
    return_mode        the return modes ("strongest", "last", "dual"); needs a [beam]
                       divergence, and [beam] return_mode is the default

How the firing follows a rate other than the preset's ``frequency_hz``:
``firing_cycle_us`` (a fixed cycle) keeps its cycle and the firing count follows;
``firings_per_rotation`` (motor-locked) keeps its count per rotation within a nominal
mode, and between nominal modes keeps the firing rate of the preset's own mode
(count x nominal rate, e.g. 2,000 at 10 Hz -> 1,000 at 20 Hz); ``horizontal_resolution_deg``
keeps its azimuth step; ``points_per_second`` keeps its point rate.
"""

import dataclasses
import re
import threading

from . import schema as sch
from .families.spinning import check_spinning
from ..errors import PresetError, SettingsError

MODES_KEYS = {"rotation_hz", "rotation_range_hz", "lidar_mode", "return_mode"}
ROTATION_TOLERANCE = 0.02   # a measured rate within 2 % of a nominal mode is that mode
LIDAR_MODE_RE = re.compile(r"^([1-9][0-9]{1,4})x([1-9][0-9]{0,2})$")
RETURN_MODES = ("strongest", "last", "dual")


@dataclasses.dataclass(frozen=True)
class Modes:
    rotation_hz: tuple = ()           # nominal rates; () = only the preset's frequency_hz
    rotation_range_hz: tuple = None   # (lowest, highest) or None
    lidar_modes: tuple = ()           # ("1024x10", ...)
    default_lidar_mode: str = None
    return_modes: tuple = ()
    default_return_mode: str = None

    def to_dict(self):
        out = {}
        if self.rotation_hz:
            out["rotation_hz"] = list(self.rotation_hz)
        if self.rotation_range_hz:
            out["rotation_range_hz"] = list(self.rotation_range_hz)
        if self.lidar_modes:
            out["lidar_mode"] = list(self.lidar_modes)
            out["default_lidar_mode"] = self.default_lidar_mode
        if self.return_modes:
            out["return_mode"] = list(self.return_modes)
            out["default_return_mode"] = self.default_return_mode
        return out


def lidar_mode_parts(mode):
    """(columns, rate_hz) of an Ouster-style mode name like '1024x10'."""
    m = LIDAR_MODE_RE.match(mode) if isinstance(mode, str) else None
    if not m:
        raise PresetError(f"lidar mode '{mode}' must be '<columns>x<rate>', e.g. '1024x10'")
    return int(m.group(1)), float(m.group(2))


def check_modes(d, where, family, frequency_hz, scan, beam):
    """Validate a ``[modes]`` table and build its ``Modes``."""
    if not isinstance(d, dict):
        raise PresetError(f"{where}: must be a table of keys")
    sch.no_unknown(d, MODES_KEYS, where)
    if d and family != "spinning":
        raise PresetError(f"{where}: modes are defined for spinning presets only")
    rates, rng = (), None
    if "rotation_hz" in d and "rotation_range_hz" in d:
        raise PresetError(f"{where}: give 'rotation_hz' (nominal rates) or 'rotation_range_hz' "
                          f"(a range), not both")
    if "rotation_hz" in d:
        rates = tuple(sch.numlist(d, "rotation_hz", where, 0.1, 1000.0, max_len=16))
        if len(set(rates)) != len(rates):
            raise PresetError(f"{where}: key 'rotation_hz' lists a rate twice")
        if frequency_hz not in rates:
            raise PresetError(f"{where}: key 'rotation_hz' must include the preset's "
                              f"frequency_hz ({frequency_hz:g}), its default")
    if "rotation_range_hz" in d:
        lo, hi = sch.numlist(d, "rotation_range_hz", where, 0.1, 1000.0, length=2)
        if not lo <= frequency_hz <= hi:
            raise PresetError(f"{where}: key 'rotation_range_hz' [{lo:g}, {hi:g}] must contain "
                              f"the preset's frequency_hz ({frequency_hz:g})")
        rng = (lo, hi)
    lidar, default_lidar = (), None
    if "lidar_mode" in d:
        v = d["lidar_mode"]
        if not isinstance(v, list) or not 1 <= len(v) <= 32 or not all(isinstance(x, str) for x in v):
            raise PresetError(f"{where}: key 'lidar_mode' must be a list of 1..32 names like "
                              f"'1024x10'")
        if len(set(v)) != len(v):
            raise PresetError(f"{where}: key 'lidar_mode' lists a mode twice")
        if "horizontal_resolution_deg" not in scan:
            raise PresetError(f"{where}: key 'lidar_mode' needs [scan] "
                              f"'horizontal_resolution_deg' (the default mode's column step)")
        for x in v:
            try:
                lidar_mode_parts(x)
            except PresetError as exc:
                raise PresetError(f"{where}: key 'lidar_mode': {exc}") from None
        if rates or rng:
            raise PresetError(f"{where}: key 'lidar_mode' sets the rotation rate; leave out "
                              f"'rotation_hz' and 'rotation_range_hz'")
        lidar = tuple(v)
        cols = round(360.0 / float(scan["horizontal_resolution_deg"]))
        for x in lidar:
            c, r = lidar_mode_parts(x)
            if c == cols and r == frequency_hz:
                default_lidar = x
        if default_lidar is None:
            raise PresetError(f"{where}: key 'lidar_mode' must include the preset's own mode "
                              f"'{cols}x{frequency_hz:g}' (frequency_hz and "
                              f"horizontal_resolution_deg), its default")
    returns, default_return = (), None
    if "return_mode" in d:
        v = d["return_mode"]
        if not isinstance(v, list) or not v or any(x not in RETURN_MODES for x in v) \
                or len(set(v)) != len(v):
            raise PresetError(f"{where}: key 'return_mode' must list some of "
                              f"{', '.join(RETURN_MODES)}, each once")
        if beam is None or not getattr(beam, "sampled", False):
            raise PresetError(f"{where}: key 'return_mode' needs a [beam] divergence (a second "
                              f"return comes from the beam's footprint)")
        if beam.return_mode not in v:
            raise PresetError(f"{where}: key 'return_mode' must include [beam] return_mode "
                              f"'{beam.return_mode}', the default")
        returns, default_return = tuple(v), beam.return_mode
    return Modes(rates, rng, lidar, default_lidar, returns, default_return)


def nominal_rate(preset, rotation_hz, lidar_mode=None):
    """The nominal rate (Hz) of the mode ``rotation_hz`` runs in, or a ``SettingsError``
    saying which rates ``preset`` allows."""
    modes = preset.modes or Modes()
    if lidar_mode is not None:
        allowed = (lidar_mode_parts(lidar_mode)[1],)
    elif modes.rotation_range_hz:
        lo, hi = modes.rotation_range_hz
        if not lo <= rotation_hz <= hi:
            raise SettingsError(f"rotation_hz {rotation_hz:g} Hz is outside what '{preset.id}' "
                                f"allows: {lo:g}-{hi:g} Hz")
        return float(rotation_hz)
    else:
        allowed = modes.rotation_hz or (preset.frequency_hz,)
    best = min(allowed, key=lambda r: abs(r - rotation_hz))
    if abs(rotation_hz - best) > ROTATION_TOLERANCE * best:
        listed = ", ".join(f"{r:g}" for r in allowed)
        raise SettingsError(f"rotation_hz {rotation_hz:g} Hz is not a rate '{preset.id}' runs "
                            f"at{' in lidar mode ' + lidar_mode if lidar_mode else ''}: "
                            f"{listed} Hz (a measured rate may differ from one by up to "
                            f"{ROTATION_TOLERANCE:.0%})")
    return float(best)


def _number_ok(value, what):
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value == value \
            or value in (float("inf"), float("-inf")) or value <= 0:
        raise SettingsError(f"{what} must be a positive number, got {value!r}")


def with_modes(preset, rotation_hz=None, lidar_mode=None, return_mode=None):
    """``preset`` as a unit set to these modes runs (None: the preset's default), a new
    validated ``DevicePreset`` (the same object when nothing changes)."""
    _number_ok(rotation_hz, "rotation_hz (Hz)")
    modes = getattr(preset, "modes", None) or Modes()
    if lidar_mode is not None and lidar_mode not in modes.lidar_modes:
        offered = ", ".join(modes.lidar_modes) or "none (the preset lists no lidar modes)"
        raise SettingsError(f"lidar mode '{lidar_mode}' is not one of '{preset.id}': {offered}")
    if return_mode not in (None, "preset") and modes.return_modes \
            and return_mode not in modes.return_modes:
        raise SettingsError(f"return mode '{return_mode}' is not one of '{preset.id}': "
                            f"{', '.join(modes.return_modes)}")
    if rotation_hz is None and (lidar_mode is None or lidar_mode == modes.default_lidar_mode):
        return preset
    if preset.family != "spinning":
        raise SettingsError(f"'{preset.id}' is a {preset.family} device: rotation rates and "
                            f"lidar modes are settings of spinning devices")
    key = (id(preset), rotation_hz, lidar_mode)
    with _LOCK:
        got = _CACHE.get(key)
        if got is not None and got[0] is preset:
            return got[1]
    derived = _derive(preset, modes, rotation_hz, lidar_mode)
    with _LOCK:
        if len(_CACHE) >= 64:
            _CACHE.clear()
        _CACHE[key] = (preset, derived)
    return derived


_CACHE = {}
_LOCK = threading.Lock()


def _derive(preset, modes, rotation_hz, lidar_mode):
    scan = dict(preset.scan)
    if lidar_mode is not None:
        cols, rate = lidar_mode_parts(lidar_mode)
        scan["horizontal_resolution_deg"] = 360.0 / cols
        nominal = rate
        freq = rate
    else:
        nominal = preset.frequency_hz
        freq = preset.frequency_hz
    if rotation_hz is not None:
        nominal = nominal_rate(preset, rotation_hz, lidar_mode)
        freq = float(rotation_hz)
    if "firings_per_rotation" in scan:
        # one firing per azimuth step of the nominal mode: the firing rate of the
        # preset's own mode, count x rate, shared by every nominal mode
        scan["firings_per_rotation"] = max(1, round(
            int(preset.scan["firings_per_rotation"]) * preset.frequency_hz / nominal))
    where = f"{preset.path or preset.id} at {freq:g} Hz" + \
        (f", lidar mode {lidar_mode}" if lidar_mode else "")
    offsets = None
    if getattr(preset, "firing_times", None) is not None:
        offsets = preset.firing_times.offsets_us(preset.table.channel_ids,
                                                 float(scan.get("firing_time_zero_us", 0.0)))
    rows = None if preset.table is None else len(preset.table.elevations_deg)
    try:
        rays = check_spinning(scan, where, freq, rows, offsets)
    except PresetError as exc:
        raise SettingsError(f"'{preset.id}' cannot run at {freq:g} Hz: {exc}") from None
    out = dataclasses.replace(preset, frequency_hz=freq, scan=scan, rays_per_frame=rays)
    out.__dict__.pop("_pattern_cache", None)
    return out


def modes_record(preset, rotation_hz=None, lidar_mode=None):
    """The sidecar's record of the modes a scan ran in."""
    modes = getattr(preset, "modes", None) or Modes()
    return {"rotation_hz": preset.frequency_hz,
            "rotation_hz_setting": rotation_hz,
            "lidar_mode": lidar_mode or modes.default_lidar_mode}
