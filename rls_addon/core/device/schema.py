"""Schema checks for preset files: typed getters, ``[detection]`` and ``[beam]``; each
family checks its own ``[scan]`` table with these (``families``).

Every error names the file (``where``), the key and what was expected. Unknown keys are
errors too, so a typo cannot silently fall back to a default.
"""

import math
import re

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
