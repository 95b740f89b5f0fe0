"""Schema checks for preset files: typed getters and the ``[scan]`` table of each family.

Every error names the file (``where``), the key and what was expected. Unknown keys are
errors too, so a typo cannot silently fall back to a default.
"""

import math
import re

from .angle_tables import AZIMUTH_CONVENTIONS
from ..errors import PresetError

MAX_RAYS_PER_FRAME = 10_000_000
MAX_CHANNELS = 1024
MAX_LIST = 1024
ID_RE = re.compile(r"^[a-z0-9][a-z0-9_.-]{0,63}$")


def num(d, key, where, lo=None, hi=None, default=None):
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


def integer(d, key, where, lo, hi, default=None):
    if key not in d and default is not None:
        return int(default)
    if key not in d:
        raise PresetError(f"{where}: missing key '{key}' (expected an integer)")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int):
        raise PresetError(f"{where}: key '{key}' must be an integer, got {type(v).__name__}")
    if not lo <= v <= hi:
        raise PresetError(f"{where}: key '{key}' must be an integer in {lo}..{hi}, got {v}")
    return v


def string(d, key, where, default=None, max_len=2000):
    if key not in d and default is not None:
        return default
    v = d.get(key)
    if not isinstance(v, str) or not v.strip():
        raise PresetError(f"{where}: key '{key}' must be a non-empty string")
    if len(v) > max_len:
        raise PresetError(f"{where}: key '{key}' is longer than {max_len} characters")
    return v


def choice(d, key, where, options, default=None):
    v = string(d, key, where, default=default)
    if v not in options:
        raise PresetError(f"{where}: key '{key}' must be one of {', '.join(options)}, got '{v}'")
    return v


def numlist(d, key, where, lo=None, hi=None, min_len=1, max_len=MAX_LIST, length=None):
    v = d.get(key)
    if not isinstance(v, list):
        raise PresetError(f"{where}: key '{key}' must be a list of numbers")
    if length is not None and len(v) != length:
        raise PresetError(f"{where}: key '{key}' must have {length} entries, got {len(v)}")
    if not min_len <= len(v) <= max_len:
        raise PresetError(f"{where}: key '{key}' must have {min_len}..{max_len} entries, got {len(v)}")
    return [num({key: x}, key, where, lo, hi) for x in v]


def no_unknown(d, allowed, where):
    extra = sorted(set(d) - set(allowed))
    if extra:
        raise PresetError(f"{where}: unknown key '{extra[0]}' (allowed: {', '.join(sorted(allowed))})")


def table_of(d, key, where):
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise PresetError(f"{where}: [{key}] must be a table of keys")
    return v


# ---- [scan] per family ---------------------------------------------------------------

SPINNING_KEYS = {
    "table", "table_source", "table_note", "elevations_deg", "azimuth_offsets_deg",
    "azimuth_convention", "channels", "upper_fov_deg", "lower_fov_deg",
    "points_per_second", "horizontal_resolution_deg", "firing_cycle_us",
    "firing_offsets_us", "firing_step_us", "firing_group_size", "firing_groups",
    "beam_origins_m",
    "firings_per_rotation", "firing_times", "firing_time_zero_us",
}
RATE_KEYS = ("points_per_second", "horizontal_resolution_deg", "firing_cycle_us",
             "firings_per_rotation")
MEMS_KEYS = {
    "model", "points_per_second", "h_mirror_hz", "v_mirror_hz", "h_amplitude_deg",
    "upper_amplitude_deg", "lower_amplitude_deg", "v_phase_deg", "zones",
    "mirror_hz", "h_fov_deg", "v_fov_deg", "phase_deg",
}
RISLEY_KEYS = {"pulse_rate_hz", "rotation_hz", "wedge_deg", "refractive_index", "fan_deg", "phase_deg"}
CUSTOM_KEYS = {"file"}
MEMS_MODELS = ("lissajous_zones", "blickfeld")


def check_spinning(s, where, frequency_hz, table_rows=None, firing_times_us=None):
    """Validate a spinning [scan]; ``table_rows`` is the row count of a resolved table,
    ``firing_times_us`` the per-channel offsets read from its ``firing_times`` file
    (``firing_times.read_firing_times``) plus ``firing_time_zero_us``."""
    no_unknown(s, SPINNING_KEYS, where)
    sources = [k for k in ("table", "elevations_deg", "channels") if k in s]
    if len(sources) != 1:
        raise PresetError(f"{where}: give exactly one of 'table', 'elevations_deg' or "
                          f"'channels' (+ 'upper_fov_deg', 'lower_fov_deg'), got {sources or 'none'}")
    if "table" in s:
        if table_rows is None:
            raise PresetError(f"{where}: key 'table' needs a preset file to resolve it against")
        c = table_rows
        choice(s, "azimuth_convention", where, tuple(AZIMUTH_CONVENTIONS))
        if "azimuth_offsets_deg" in s:
            raise PresetError(f"{where}: key 'azimuth_offsets_deg' cannot be combined with 'table'")
    elif "elevations_deg" in s:
        c = len(numlist(s, "elevations_deg", where, -90.0, 90.0, max_len=MAX_CHANNELS))
        if "azimuth_offsets_deg" in s:
            numlist(s, "azimuth_offsets_deg", where, -360.0, 360.0, length=c)
        choice(s, "azimuth_convention", where, tuple(AZIMUTH_CONVENTIONS), default="ccw")
    else:
        c = integer(s, "channels", where, 1, MAX_CHANNELS)
        up = num(s, "upper_fov_deg", where, -90.0, 90.0)
        lo = num(s, "lower_fov_deg", where, -90.0, 90.0)
        if lo > up:
            raise PresetError(f"{where}: 'lower_fov_deg' ({lo}) must not exceed 'upper_fov_deg' ({up})")
        for k in ("azimuth_offsets_deg", "azimuth_convention"):
            if k in s:
                raise PresetError(f"{where}: key '{k}' needs a 'table' or 'elevations_deg'")
    for k in ("table_source", "table_note"):
        if k in s:
            string(s, k, where)
    rates = [k for k in RATE_KEYS if k in s]
    if len(rates) != 1:
        raise PresetError(f"{where}: give exactly one of {', '.join(repr(k) for k in RATE_KEYS)}"
                          f", got {rates or 'none'}")
    period = 1.0 / frequency_hz
    if "points_per_second" in s:
        pps = num(s, "points_per_second", where, 1.0, 1e9)
        rays = pps * period
        cycle_us = period / max(1, round(rays / c)) * 1e6
    elif "horizontal_resolution_deg" in s:
        res = num(s, "horizontal_resolution_deg", where, 1e-4, 360.0)
        rays = round(360.0 / res) * c
        cycle_us = period / round(360.0 / res) * 1e6
    elif "firings_per_rotation" in s:
        n = integer(s, "firings_per_rotation", where, 1, MAX_RAYS_PER_FRAME)
        rays = n * c
        cycle_us = period / n * 1e6
    else:
        cycle_us = num(s, "firing_cycle_us", where, 0.01, period * 1e6)
        rays = math.floor(period / (cycle_us * 1e-6)) * c
    if rays > MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {MAX_RAYS_PER_FRAME}")
    if rays < c:
        raise PresetError(f"{where}: rate too low for one firing per revolution")
    if "firing_time_zero_us" in s and "firing_times" not in s:
        raise PresetError(f"{where}: key 'firing_time_zero_us' needs 'firing_times'")
    if "firing_times" in s:
        others = [k for k in ("firing_offsets_us", "firing_step_us", "firing_group_size",
                              "firing_groups") if k in s]
        if others:
            raise PresetError(f"{where}: key 'firing_times' excludes '{others[0]}'")
        if "table" not in s:
            raise PresetError(f"{where}: key 'firing_times' needs a 'table' (its channel ids)")
        string(s, "firing_times", where)
        num(s, "firing_time_zero_us", where, -1e6, 1e6, default=0.0)
        if firing_times_us is None:
            raise PresetError(f"{where}: key 'firing_times' needs a preset file to resolve it against")
        check_firing_offsets(firing_times_us, cycle_us, f"{where} key 'firing_times' "
                             f"(+ 'firing_time_zero_us')")
    elif "firing_offsets_us" in s:
        if any(k in s for k in ("firing_step_us", "firing_group_size", "firing_groups")):
            raise PresetError(f"{where}: key 'firing_offsets_us' excludes 'firing_step_us' and groups")
        offs = numlist(s, "firing_offsets_us", where, 0.0, 1e6, length=c)
        if max(offs) >= cycle_us:
            raise PresetError(f"{where}: key 'firing_offsets_us' must stay below the firing cycle "
                              f"({cycle_us:.3f} us)")
    elif "firing_step_us" in s:
        step = num(s, "firing_step_us", where, 0.0, 1e6)
        if "firing_groups" in s:
            if "firing_group_size" in s:
                raise PresetError(f"{where}: give 'firing_groups' or 'firing_group_size', not both")
            groups = numlist(s, "firing_groups", where, 0, MAX_CHANNELS, length=c)
            if any(g != int(g) for g in groups):
                raise PresetError(f"{where}: key 'firing_groups' must hold integers")
            last = max(groups)
        else:
            size = integer(s, "firing_group_size", where, 1, MAX_CHANNELS, default=1)
            last = (c - 1) // size
        if last * step >= cycle_us:
            raise PresetError(f"{where}: firing sequence ({last} x {step} us) does not fit in the "
                              f"firing cycle ({cycle_us:.3f} us)")
    elif any(k in s for k in ("firing_group_size", "firing_groups")):
        raise PresetError(f"{where}: firing groups need 'firing_step_us'")
    return int(rays)


def check_beam_origins(s, where, channels, table_origins=False):
    """Validate ``beam_origins_m`` of a spinning [scan]: where the beams leave from, in
    metres in the head frame (+X the head's direction, +Y left, +Z up), as one [x, y, z]
    for every beam (Ouster's beam-origin ring: [lidar_origin_to_beam_origin, 0, 0]) or one
    per channel. Returns an (1 or C, 3) list of lists, or None when absent; a table with
    origin columns gives them there instead."""
    if "beam_origins_m" not in s:
        return None
    if table_origins:
        raise PresetError(f"{where}: key 'beam_origins_m' cannot be combined with a table "
                          f"that has origin columns")
    v = s["beam_origins_m"]
    if not isinstance(v, list) or len(v) not in (1, channels) \
            or not all(isinstance(x, list) for x in v):
        raise PresetError(f"{where}: key 'beam_origins_m' must be a list of [x, y, z] (metres): "
                          f"one for every beam or one per channel ({channels})")
    return [numlist({"beam_origins_m": x}, "beam_origins_m", where, -1.0, 1.0, length=3)
            for x in v]


def check_firing_offsets(offsets_us, cycle_us, what):
    """Every channel's firing offset must lie in [0, cycle): a channel fires within its
    own firing cycle, or the next cycle's firing would come first."""
    lo, hi = min(offsets_us), max(offsets_us)
    if lo < 0.0 or hi >= cycle_us:
        raise PresetError(f"{what}: the channels fire {lo:.3f}..{hi:.3f} us into the cycle, "
                          f"which must lie within 0..{cycle_us:.3f} us (the firing cycle)")


def check_mems(s, where, frequency_hz):
    no_unknown(s, MEMS_KEYS, where)
    model = choice(s, "model", where, MEMS_MODELS)
    pps = num(s, "points_per_second", where, 1.0, 1e9)
    lis = {"h_mirror_hz", "v_mirror_hz", "h_amplitude_deg", "upper_amplitude_deg",
           "lower_amplitude_deg", "v_phase_deg", "zones"}
    blk = {"mirror_hz", "h_fov_deg", "v_fov_deg", "phase_deg"}
    no_unknown(s, {"model", "points_per_second"} | (lis if model == "lissajous_zones" else blk), where)
    if model == "lissajous_zones":
        for k in ("h_mirror_hz", "v_mirror_hz"):
            num(s, k, where, 0.0, 1e6)
        for k in ("h_amplitude_deg", "upper_amplitude_deg", "lower_amplitude_deg"):
            num(s, k, where, 0.0, 90.0)
        num(s, "v_phase_deg", where, -360.0, 360.0, default=90.0)
        zones = s.get("zones")
        if not isinstance(zones, list) or not 1 <= len(zones) <= 64:
            raise PresetError(f"{where}: key 'zones' must be a list of 1..64 "
                              f"[offset_deg, rotation_deg, c_upper_deg, c_lower_deg] entries")
        for i, z in enumerate(zones):
            numlist({"zones": z}, "zones", f"{where} zone {i + 1}", -180.0, 180.0, length=4)
        beams = 2 * len(zones)
    else:
        num(s, "mirror_hz", where, 0.0, 1e6)
        num(s, "h_fov_deg", where, 0.0, 180.0)
        num(s, "v_fov_deg", where, 0.0, 180.0)
        num(s, "phase_deg", where, -360.0, 360.0, default=90.0)
        beams = 1
    rays = pps / frequency_hz
    if rays > MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {MAX_RAYS_PER_FRAME}")
    if rays < beams:
        raise PresetError(f"{where}: 'points_per_second' too low for one ray per beam per frame")
    return int(rays)


def check_risley(s, where, frequency_hz):
    no_unknown(s, RISLEY_KEYS, where)
    rate = num(s, "pulse_rate_hz", where, 1.0, 1e8)
    f = numlist(s, "rotation_hz", where, -1e5, 1e5, max_len=3)
    numlist(s, "wedge_deg", where, -60.0, 60.0, length=len(f))
    if "phase_deg" in s:
        numlist(s, "phase_deg", where, -360.0, 360.0, length=len(f))
    num(s, "refractive_index", where, 1.0001, 4.0)
    fan = numlist(s, "fan_deg", where, -45.0, 45.0, max_len=256) if "fan_deg" in s else [0.0]
    rays = math.floor(rate / frequency_hz + 1e-9) * len(fan)
    if rays > MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {MAX_RAYS_PER_FRAME}")
    if rays < 1:
        raise PresetError(f"{where}: 'pulse_rate_hz' too low for one ray per frame")
    return int(rays)


def check_custom(s, where):
    no_unknown(s, CUSTOM_KEYS, where)
    string(s, "file", where)


# ---- [detection] ----------------------------------------------------------------------

DETECTION_KEYS = {"range_at_reflectivity", "probability_at_range", "intensity",
                  "logistic_width"}
MAX_FIGURES = 16


def check_detection(d, where):
    """Validate a ``[detection]`` table and build its ``DetectionModel``:
    ``range_at_reflectivity = [[reflectivity 0..1, range m], ...]`` (1..16 datasheet
    figures), optional ``probability_at_range`` (what a figure stands for, default
    0.9), ``intensity`` (reflectivity | strength | carla, default reflectivity) and
    ``logistic_width`` (in ln received power, default 0.164)."""
    from ..physics.detection import (
        DEFAULT_PROBABILITY,
        DEFAULT_WIDTH,
        INTENSITY_MODES,
        DetectionModel,
    )

    if not isinstance(d, dict):
        raise PresetError(f"{where}: must be a table of keys")
    no_unknown(d, DETECTION_KEYS, where)
    figs = d.get("range_at_reflectivity")
    shape = ("a list of [reflectivity, range_m] pairs, e.g. [[0.10, 90.0], [0.80, 260.0]] "
             "(reflectivity 0..1, range in metres)")
    if not isinstance(figs, list) or not 1 <= len(figs) <= MAX_FIGURES:
        got = "nothing" if figs is None else f"{len(figs)} entries" \
            if isinstance(figs, list) else f"a {type(figs).__name__}"
        raise PresetError(f"{where}: key 'range_at_reflectivity' must be {shape} "
                          f"(1..{MAX_FIGURES} of them), got {got}")
    figures = []
    for i, f in enumerate(figs):
        if not isinstance(f, list) or len(f) != 2 or any(
                isinstance(x, bool) or not isinstance(x, (int, float)) for x in f):
            raise PresetError(f"{where}: key 'range_at_reflectivity' entry {i + 1} must be "
                              f"[reflectivity, range_m], got {f!r}")
        rho, r = float(f[0]), float(f[1])
        if not (math.isfinite(rho) and 0.0 < rho <= 1.0):
            raise PresetError(f"{where}: key 'range_at_reflectivity' entry {i + 1}: the "
                              f"reflectivity must be in (0, 1] (0.10 for 10 %), got {f[0]!r}")
        if not (math.isfinite(r) and 0.01 <= r <= 1e5):
            raise PresetError(f"{where}: key 'range_at_reflectivity' entry {i + 1}: the "
                              f"range must be 0.01..100000 m, got {f[1]!r}")
        figures.append((rho, r))
    if len({rho for rho, _ in figures}) != len(figures):
        raise PresetError(f"{where}: key 'range_at_reflectivity' gives one reflectivity twice")
    prob = num(d, "probability_at_range", where, default=DEFAULT_PROBABILITY)
    if not 0.5 <= prob <= 0.999:
        raise PresetError(f"{where}: key 'probability_at_range' must be in 0.5..0.999 (the "
                          f"detection probability a figure stands for), got {prob}")
    width = num(d, "logistic_width", where, lo=0.01, hi=2.0, default=DEFAULT_WIDTH)
    intensity = choice(d, "intensity", where, INTENSITY_MODES, default="reflectivity")
    return DetectionModel(tuple(figures), prob, intensity, width)


# ---- [beam] ---------------------------------------------------------------------------

BEAM_KEYS = {"divergence_rad", "return_mode", "echo_separation_m"}


def check_beam(d, where):
    """Validate a ``[beam]`` table and build its ``footprint.Beam``: ``divergence_rad``
    (the full divergence angle, one number or [horizontal, vertical], 0..0.1 rad),
    optional ``return_mode`` (strongest | last | dual, default strongest) and
    ``echo_separation_m`` (two echoes closer than this are one, default 1 m)."""
    from ..physics.footprint import ECHO_SEPARATION_M, RETURN_MODES, Beam

    if not isinstance(d, dict):
        raise PresetError(f"{where}: must be a table of keys")
    no_unknown(d, BEAM_KEYS, where)
    div = d.get("divergence_rad", 0.0)
    if isinstance(div, list):
        hv = numlist(d, "divergence_rad", where, 0.0, 0.1, length=2)
    else:
        hv = [num(d, "divergence_rad", where, 0.0, 0.1, default=0.0)] * 2
    mode = choice(d, "return_mode", where, RETURN_MODES, default="strongest")
    sep = num(d, "echo_separation_m", where, 0.01, 100.0, default=ECHO_SEPARATION_M)
    return Beam(tuple(hv), mode, sep)
