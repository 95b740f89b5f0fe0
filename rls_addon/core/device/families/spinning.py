"""The spinning family: multi-beam heads turning a full circle (Velodyne, Hesai,
Ouster, RoboSense) and CARLA's uniform channels. Its ``[scan]`` keys and their check
(angle tables and vendor firing times read here), the channels' geometry, and the
pattern of a preset (``patterns.spinning``)."""

import math

import numpy as np

from .. import schema as sch
from ..angle_tables import AZIMUTH_CONVENTIONS, ccw_offsets_deg, read_angle_table, resolve_table_path
from ..firing_times import read_firing_times
from ..patterns.spinning import spinning_pattern, uniform_elevations_deg
from ...errors import PresetError

SCAN_KEYS = frozenset({
    "table", "table_source", "table_note", "elevations_deg", "azimuth_offsets_deg",
    "azimuth_convention", "channels", "upper_fov_deg", "lower_fov_deg",
    "points_per_second", "horizontal_resolution_deg", "firing_cycle_us",
    "firing_offsets_us", "firing_step_us", "firing_group_size", "firing_groups",
    "beam_origins_m",
    "firings_per_rotation", "firing_times", "firing_time_zero_us",
})
RATE_KEYS = ("points_per_second", "horizontal_resolution_deg", "firing_cycle_us",
             "firings_per_rotation")


def check(scan, where, frequency_hz, base_dir):
    """Validate a spinning ``[scan]``: ``(rays per frame, {"table", "firing_times"})``,
    the angle table and vendor firing times it names read and checked."""
    table = None
    if "table" in scan:
        if base_dir is None:
            raise PresetError(f"{where}: key 'table' needs a preset file to resolve it against")
        tpath = resolve_table_path(scan["table"], base_dir, where)
        table = read_angle_table(tpath, f"{where} table '{scan['table']}'")
    firing, offsets = None, None
    if "firing_times" in scan and table is not None:
        fpath = resolve_table_path(scan["firing_times"], base_dir, where)
        firing = read_firing_times(fpath, table.channel_ids,
                                   f"{where} firing_times '{scan['firing_times']}'")
        zero = sch.num(scan, "firing_time_zero_us", where, -1e6, 1e6, default=0.0)
        offsets = firing.offsets_us(table.channel_ids, zero)
    rays = check_spinning(scan, where, frequency_hz,
                          None if table is None else len(table.elevations_deg), offsets)
    check_beam_origins(scan, where, channel_count(scan, table),
                       table is not None and table.origins_m is not None)
    return rays, {"table": table, "firing_times": firing}


def check_spinning(s, where, frequency_hz, table_rows=None, firing_times_us=None):
    """Validate a spinning [scan]; ``table_rows`` is the row count of a resolved table,
    ``firing_times_us`` the per-channel offsets read from its ``firing_times`` file
    (``firing_times.read_firing_times``) plus ``firing_time_zero_us``."""
    sources = [k for k in ("table", "elevations_deg", "channels") if k in s]
    if len(sources) != 1:
        raise PresetError(f"{where}: give exactly one of 'table', 'elevations_deg' or "
                          f"'channels' (+ 'upper_fov_deg', 'lower_fov_deg'), got {sources or 'none'}")
    if "table" in s:
        if table_rows is None:
            raise PresetError(f"{where}: key 'table' needs a preset file to resolve it against")
        c = table_rows
        sch.choice(s, "azimuth_convention", where, tuple(AZIMUTH_CONVENTIONS))
        if "azimuth_offsets_deg" in s:
            raise PresetError(f"{where}: key 'azimuth_offsets_deg' cannot be combined with 'table'")
    elif "elevations_deg" in s:
        c = len(sch.numlist(s, "elevations_deg", where, -90.0, 90.0, max_len=sch.MAX_CHANNELS))
        if "azimuth_offsets_deg" in s:
            sch.numlist(s, "azimuth_offsets_deg", where, -360.0, 360.0, length=c)
        sch.choice(s, "azimuth_convention", where, tuple(AZIMUTH_CONVENTIONS), default="ccw")
    else:
        c = sch.integer(s, "channels", where, 1, sch.MAX_CHANNELS)
        up = sch.num(s, "upper_fov_deg", where, -90.0, 90.0)
        lo = sch.num(s, "lower_fov_deg", where, -90.0, 90.0)
        if lo > up:
            raise PresetError(f"{where}: 'lower_fov_deg' ({lo}) must not exceed 'upper_fov_deg' ({up})")
        for k in ("azimuth_offsets_deg", "azimuth_convention"):
            if k in s:
                raise PresetError(f"{where}: key '{k}' needs a 'table' or 'elevations_deg'")
    for k in ("table_source", "table_note"):
        if k in s:
            sch.string(s, k, where)
    rates = [k for k in RATE_KEYS if k in s]
    if len(rates) != 1:
        raise PresetError(f"{where}: give exactly one of {', '.join(repr(k) for k in RATE_KEYS)}"
                          f", got {rates or 'none'}")
    period = 1.0 / frequency_hz
    if "points_per_second" in s:
        pps = sch.num(s, "points_per_second", where, 1.0, 1e9)
        rays = pps * period
        cycle_us = period / max(1, round(rays / c)) * 1e6
    elif "horizontal_resolution_deg" in s:
        res = sch.num(s, "horizontal_resolution_deg", where, 1e-4, 360.0)
        rays = round(360.0 / res) * c
        cycle_us = period / round(360.0 / res) * 1e6
    elif "firings_per_rotation" in s:
        n = sch.integer(s, "firings_per_rotation", where, 1, sch.MAX_RAYS_PER_FRAME)
        rays = n * c
        cycle_us = period / n * 1e6
    else:
        cycle_us = sch.num(s, "firing_cycle_us", where, 0.01, period * 1e6)
        rays = math.floor(period / (cycle_us * 1e-6)) * c
    if rays > sch.MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {sch.MAX_RAYS_PER_FRAME}")
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
        sch.string(s, "firing_times", where)
        sch.num(s, "firing_time_zero_us", where, -1e6, 1e6, default=0.0)
        if firing_times_us is None:
            raise PresetError(f"{where}: key 'firing_times' needs a preset file to resolve it against")
        check_firing_offsets(firing_times_us, cycle_us, f"{where} key 'firing_times' "
                             f"(+ 'firing_time_zero_us')")
    elif "firing_offsets_us" in s:
        if any(k in s for k in ("firing_step_us", "firing_group_size", "firing_groups")):
            raise PresetError(f"{where}: key 'firing_offsets_us' excludes 'firing_step_us' and groups")
        offs = sch.numlist(s, "firing_offsets_us", where, 0.0, 1e6, length=c)
        if max(offs) >= cycle_us:
            raise PresetError(f"{where}: key 'firing_offsets_us' must stay below the firing cycle "
                              f"({cycle_us:.3f} us)")
    elif "firing_step_us" in s:
        step = sch.num(s, "firing_step_us", where, 0.0, 1e6)
        if "firing_groups" in s:
            if "firing_group_size" in s:
                raise PresetError(f"{where}: give 'firing_groups' or 'firing_group_size', not both")
            groups = sch.numlist(s, "firing_groups", where, 0, sch.MAX_CHANNELS, length=c)
            if any(g != int(g) for g in groups):
                raise PresetError(f"{where}: key 'firing_groups' must hold integers")
            last = max(groups)
        else:
            size = sch.integer(s, "firing_group_size", where, 1, sch.MAX_CHANNELS, default=1)
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
    return [sch.numlist({"beam_origins_m": x}, "beam_origins_m", where, -1.0, 1.0, length=3)
            for x in v]


def check_firing_offsets(offsets_us, cycle_us, what):
    """Every channel's firing offset must lie in [0, cycle): a channel fires within its
    own firing cycle, or the next cycle's firing would come first."""
    lo, hi = min(offsets_us), max(offsets_us)
    if lo < 0.0 or hi >= cycle_us:
        raise PresetError(f"{what}: the channels fire {lo:.3f}..{hi:.3f} us into the cycle, "
                          f"which must lie within 0..{cycle_us:.3f} us (the firing cycle)")


def spinning_elevations_offsets(preset):
    """(elevations_deg, azimuth offsets in our ccw convention) of a spinning preset."""
    s = preset.scan
    if preset.table is not None:
        el = np.asarray(preset.table.elevations_deg, dtype=np.float64)
        off = ccw_offsets_deg(preset.table.azimuth_offsets_deg, s["azimuth_convention"])
    elif "elevations_deg" in s:
        el = np.asarray(s["elevations_deg"], dtype=np.float64)
        raw = s.get("azimuth_offsets_deg", [0.0] * len(el))
        off = ccw_offsets_deg(raw, s.get("azimuth_convention", "ccw"))
    else:
        el = uniform_elevations_deg(s["channels"], s["upper_fov_deg"], s["lower_fov_deg"])
        off = np.zeros_like(el)
    return el, off


def channel_count(s, table):
    """Channels of a spinning ``[scan]`` ``s`` with its resolved angle ``table``."""
    if table is not None:
        return len(table.elevations_deg)
    return len(s["elevations_deg"]) if "elevations_deg" in s else int(s["channels"])


def spinning_beam_origins(preset):
    """Where each beam of a spinning preset leaves from, (C or 1, 3) metres in the head
    frame (table origin columns or ``beam_origins_m``), or None: all from the origin."""
    if preset.table is not None and preset.table.origins_m is not None:
        return np.asarray(preset.table.origins_m, np.float64)
    if "beam_origins_m" in preset.scan:
        return np.asarray(preset.scan["beam_origins_m"], np.float64).reshape(-1, 3)
    return None


def _firing_offsets_s(s, c, preset=None):
    times = getattr(preset, "firing_times", None)
    if times is not None:
        zero = float(s.get("firing_time_zero_us", 0.0))
        return np.asarray(times.offsets_us(preset.table.channel_ids, zero)) * 1e-6
    if "firing_offsets_us" in s:
        return np.asarray(s["firing_offsets_us"], dtype=np.float64) * 1e-6
    if "firing_step_us" in s:
        if "firing_groups" in s:
            groups = np.asarray(s["firing_groups"], dtype=np.float64)
        else:
            groups = np.arange(c) // int(s.get("firing_group_size", 1))
        return groups * float(s["firing_step_us"]) * 1e-6
    return None


def build(p, frame):
    """The ``ScanPattern`` of a spinning preset (the same for every frame)."""
    s = p.scan
    el, off = spinning_elevations_offsets(p)
    cycle = s.get("firing_cycle_us")
    return spinning_pattern(
        el, p.frequency_hz, s.get("points_per_second"), off,
        horizontal_resolution_deg=s.get("horizontal_resolution_deg"),
        firing_cycle_s=None if cycle is None else cycle * 1e-6,
        firings_per_rotation=s.get("firings_per_rotation"),
        firing_offsets_s=_firing_offsets_s(s, len(el), p),
        origins_head_m=spinning_beam_origins(p))
