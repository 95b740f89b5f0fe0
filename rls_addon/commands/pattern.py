"""``rls pattern``: write the rays of a device's scan pattern to CSV (no bpy)."""

import io
from pathlib import Path

import numpy as np

from ..core.errors import OutputError
from ..core.output.io import atomic_write_bytes


def add_parser(sub):
    p = sub.add_parser("pattern", help="write a device's scan pattern to CSV",
                       description="Write time_s,azimuth_deg,elevation_deg,channel for every ray "
                                   "fired in the given duration; frames follow each other and "
                                   "times continue across frames.")
    p.add_argument("name", help="preset id, display name or path to a .toml file")
    p.add_argument("--duration", type=float, default=None,
                   help="seconds to write (default: one frame)")
    p.add_argument("--out", required=True, help="output CSV file")
    p.add_argument("--user-dir", default=None, help="also look for the preset in this folder")
    p.add_argument("--rotation-hz", type=float, default=None, metavar="HZ",
                   help="spinning devices: the rotation rate (a mode or a measured rate)")
    p.add_argument("--lidar-mode", default=None, metavar="MODE",
                   help="devices with lidar modes (Ouster): e.g. 2048x10")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")
    p.set_defaults(func=run)


def run(args):
    from ..core.device.patterns.base import angles_from_directions
    from ..core.device.patterns.custom import write_pattern_csv
    from ..core.device.modes import with_modes
    from ..core.device.presets import get_preset, pattern_span

    preset = with_modes(get_preset(args.name, args.user_dir), args.rotation_hz, args.lidar_mode)
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        raise OutputError(f"{out}: already exists (use --overwrite to replace it)")
    if not out.parent.is_dir():
        raise OutputError(f"{out.parent}: output folder does not exist")
    duration = preset.period if args.duration is None else args.duration
    times, dirs, channels = pattern_span(preset, duration)
    az, el = angles_from_directions(dirs)

    def write(binary):
        text = io.TextIOWrapper(binary, encoding="utf-8", newline="\n")
        write_pattern_csv(text, times, np.degrees(az), np.degrees(el), channels)
        text.flush()
        text.detach()  # the atomic writer closes the file itself

    atomic_write_bytes(out, write, overwrite=args.overwrite)
    print(f"{out}: {len(times)} rays of {preset.name} over {duration:g} s")
    return 0
