"""What each effect of issue 21 costs a frame: the same scene, preset and seed, the
clear-weather thin-ray frame (``footprint = "off"``) against the frame with beam
footprints (``footprint = "auto"``, strongest and dual return) and against the frame
in fog of 50 m visibility (thin rays).

Scenes: the bench street (``scene.street_geometry``, from 2 m up) and the open-sky
scene (``scene.open_sky_geometry``, from 5 m up); presets with a divergence and
datasheet figures: the Velodyne HDL-64E and the Livox Mid-40. Cold frames (the static
cast is not reused), the best of ``repeat``, with the default backend.

Targets: footprints <= 1.3x, fog <= 1.2x the clear thin-ray frame.

    .venv/bin/python -m bench.effect_costs [--quick]     (prints JSON, then markdown)
"""

import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import standalone  # noqa: E402 - after the path above

PRESETS = ("velodyne_hdl64e", "livox_mid40")
CASES = {
    "clear": {"footprint": "off"},
    "footprint": {"footprint": "auto", "return_mode": "strongest"},
    "footprint_dual": {"footprint": "auto", "return_mode": "dual"},
    "fog50": {"footprint": "off", "weather": "fog:visibility=50"},
}
TARGETS = {"footprint": 1.3, "footprint_dual": 1.3, "fog50": 1.2}


def _best(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def scene_costs(geometry, pose, preset, repeat):
    """{case: {"s": seconds, "points": n, "ratio": over clear}, ...} for one scene."""
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    scene = PreparedScene(geometry, pose[:3, 3], preset.range.max_m,
                          caster_factory("auto")[0])
    scene.reuse_casts = False
    pattern = preset.pattern()
    out = {"rays": len(pattern), "triangles": int(geometry.triangle_count)}
    # one frame first: builds, caches and the pattern's neighbour table
    scan_frame(scene, pattern, pose, preset, ScanSettings(seed=3, **CASES["footprint"]),
               frame=1)
    for name, kw in CASES.items():
        settings = ScanSettings(seed=3, **kw)
        s, res = _best(lambda st=settings: scan_frame(scene, pattern, pose, preset, st,
                                                      frame=1), repeat)
        out[name] = {"s": s, "points": len(res.points),
                     "footprint_rays": int(res.stats.get("footprint_rays", 0)),
                     "sub_rays": int(res.stats.get("footprint_sub_rays", 0)),
                     "second_returns": int(res.stats.get("second_returns", 0))}
    for name in TARGETS:
        out[name]["ratio"] = out[name]["s"] / out["clear"]["s"]
    return out


def measure(quick=False, street=None):
    """Every preset on both scenes; ``street``: the bench street if already built."""
    from bench.scene import (
        OPEN_SKY_POSE,
        SENSOR_POSE,
        open_sky_geometry,
        street_geometry,
    )
    from rls_addon.core.device.presets import get_preset

    repeat = 3 if quick else 7
    if street is None:
        street = street_geometry(300_000 if quick else 1_000_000)
    scenes = {"street": (street, SENSOR_POSE), "open_sky": (open_sky_geometry(), OPEN_SKY_POSE)}
    out = {"quick": bool(quick), "repeat": repeat, "results": {}}
    for pid in PRESETS:
        preset = get_preset(pid)
        out["results"][pid] = {"name": preset.name, **{
            name: scene_costs(g, pose, preset, repeat) for name, (g, pose) in scenes.items()}}
    out["loadavg"] = os.getloadavg()
    return out


def section(res):
    """Markdown lines of ``measure``'s result (for docs/benchmarks.md or realism.md)."""
    def ms(s):
        return f"{s * 1e3:.1f} ms"

    lines = ["## What each effect costs a frame (issue 21)\n",
             ("Cold frames (no reuse of the static cast), best of "
              f"{res['repeat']}, default backend, seed 3. *Clear* is the thin-ray frame "
              "in clear air (`footprint = off`); *footprint* samples the beam's footprint "
              "near depth edges (strongest, then dual return); *fog* is 50 m visibility "
              "with thin rays. Targets: footprint <= 1.3x, fog <= 1.2x.\n"),
             ("| preset | scene | rays | clear | footprint (strongest) | footprint (dual) | "
              "fog 50 m | sub-rays cast / rays (whole rings) |"),
             "|---|---|---|---|---|---|---|---|"]
    for r in res["results"].values():
        for scene, label in (("street", "street"), ("open_sky", "open sky")):
            c = r[scene]

            def cell(name, c=c):
                ok = "" if c[name]["ratio"] <= TARGETS[name] else " (over target)"
                return f"{ms(c[name]['s'])}, **{c[name]['ratio']:.2f}x**{ok}"

            lines.append(
                f"| {r['name']} | {label} ({c['triangles']:,} triangles) | {c['rays']:,} | "
                f"{ms(c['clear']['s'])} | {cell('footprint')} | {cell('footprint_dual')} | "
                f"{cell('fog50')} | {c['footprint']['sub_rays'] / c['rays']:.1%} "
                f"({c['footprint']['footprint_rays'] / c['rays']:.1%}) |")
    lines.append(f"\nLoad average while measured: {', '.join(f'{x:.2f}' for x in res['loadavg'])}.")
    return lines


def main(argv=None):
    return standalone.main(__doc__, measure, section, argv,
                           quick_help="a smaller street, 3 repeats")


if __name__ == "__main__":
    main()
