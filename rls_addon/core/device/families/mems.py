"""The MEMS family: mirror scanners, RoboSense M1-like Lissajous zones and Blickfeld's
two mirrors (``patterns.mems``). Its ``[scan]`` keys, their check and the pattern of a
preset, which keeps moving from frame to frame."""

from .. import schema as sch
from ..patterns.mems import blickfeld_pattern, lissajous_zones_pattern
from ...errors import PresetError

SCAN_KEYS = frozenset({
    "model", "points_per_second", "h_mirror_hz", "v_mirror_hz", "h_amplitude_deg",
    "upper_amplitude_deg", "lower_amplitude_deg", "v_phase_deg", "zones",
    "mirror_hz", "h_fov_deg", "v_fov_deg", "phase_deg",
})
MEMS_MODELS = ("lissajous_zones", "blickfeld")


def check(s, where, frequency_hz, base_dir):
    """Validate a MEMS ``[scan]``: ``(rays per frame, {})``."""
    model = sch.choice(s, "model", where, MEMS_MODELS)
    pps = sch.num(s, "points_per_second", where, 1.0, 1e9)
    lis = {"h_mirror_hz", "v_mirror_hz", "h_amplitude_deg", "upper_amplitude_deg",
           "lower_amplitude_deg", "v_phase_deg", "zones"}
    blk = {"mirror_hz", "h_fov_deg", "v_fov_deg", "phase_deg"}
    sch.no_unknown(s, {"model", "points_per_second"} | (lis if model == "lissajous_zones" else blk), where)
    if model == "lissajous_zones":
        for k in ("h_mirror_hz", "v_mirror_hz"):
            sch.num(s, k, where, 0.0, 1e6)
        for k in ("h_amplitude_deg", "upper_amplitude_deg", "lower_amplitude_deg"):
            sch.num(s, k, where, 0.0, 90.0)
        sch.num(s, "v_phase_deg", where, -360.0, 360.0, default=90.0)
        zones = s.get("zones")
        if not isinstance(zones, list) or not 1 <= len(zones) <= 64:
            raise PresetError(f"{where}: key 'zones' must be a list of 1..64 "
                              f"[offset_deg, rotation_deg, c_upper_deg, c_lower_deg] entries")
        for i, z in enumerate(zones):
            sch.numlist({"zones": z}, "zones", f"{where} zone {i + 1}", -180.0, 180.0, length=4)
        beams = 2 * len(zones)
    else:
        sch.num(s, "mirror_hz", where, 0.0, 1e6)
        sch.num(s, "h_fov_deg", where, 0.0, 180.0)
        sch.num(s, "v_fov_deg", where, 0.0, 180.0)
        sch.num(s, "phase_deg", where, -360.0, 360.0, default=90.0)
        beams = 1
    rays = pps / frequency_hz
    if rays > sch.MAX_RAYS_PER_FRAME:
        raise PresetError(f"{where}: {rays:.0f} rays per frame exceeds the limit of {sch.MAX_RAYS_PER_FRAME}")
    if rays < beams:
        raise PresetError(f"{where}: 'points_per_second' too low for one ray per beam per frame")
    return int(rays), {}


def build(p, frame):
    """The ``ScanPattern`` of frame ``frame`` of a MEMS preset."""
    s = p.scan
    if s["model"] == "blickfeld":
        return blickfeld_pattern(p.frequency_hz, s["points_per_second"], s["mirror_hz"],
                                 s["h_fov_deg"], s["v_fov_deg"], s.get("phase_deg", 90.0), frame)
    return lissajous_zones_pattern(
        p.frequency_hz, s["points_per_second"], s["zones"], s["h_mirror_hz"],
        s["v_mirror_hz"], s["h_amplitude_deg"], s["upper_amplitude_deg"],
        s["lower_amplitude_deg"], s.get("v_phase_deg", 90.0), frame)
