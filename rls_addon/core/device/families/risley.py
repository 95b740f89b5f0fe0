"""The Risley family: prism scanners (Livox), beams refracted through 1-3 turning wedges
(``patterns.risley``). Its ``[scan]`` keys, their check and the pattern of a preset,
which keeps moving from frame to frame."""

import math

from .. import schema as sch
from ..patterns.risley import risley_pattern
from ...errors import PresetError

SCAN_KEYS = frozenset({"pulse_rate_hz", "rotation_hz", "wedge_deg", "refractive_index", "fan_deg",
                       "phase_deg"})


def check(s, where, frequency_hz, base_dir):
    """Validate a Risley ``[scan]``: ``(rays per frame, {})``."""
    rate = sch.num(s, "pulse_rate_hz", where, 1.0, 1e8)
    f = sch.numlist(s, "rotation_hz", where, -1e5, 1e5, max_len=3)
    sch.numlist(s, "wedge_deg", where, -60.0, 60.0, length=len(f))
    if "phase_deg" in s:
        sch.numlist(s, "phase_deg", where, -360.0, 360.0, length=len(f))
    sch.num(s, "refractive_index", where, 1.0001, 4.0)
    fan = sch.numlist(s, "fan_deg", where, -45.0, 45.0, max_len=256) if "fan_deg" in s else [0.0]
    rays = math.floor(rate / frequency_hz + 1e-9) * len(fan)
    if rays > sch.MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {sch.MAX_RAYS_PER_FRAME}")
    if rays < 1:
        raise PresetError(f"{where}: 'pulse_rate_hz' too low for one ray per frame")
    return int(rays), {}


def build(p, frame):
    """The ``ScanPattern`` of frame ``frame`` of a Risley preset."""
    s = p.scan
    return risley_pattern(p.frequency_hz, s["pulse_rate_hz"], s["rotation_hz"], s["wedge_deg"],
                          s["refractive_index"], s.get("fan_deg", [0.0]), s.get("phase_deg"),
                          frame)
