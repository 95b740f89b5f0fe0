"""Points kept in fog, against visibility, for two presets with datasheet figures (issue
21): docs/realism_fog.png and the numbers behind it.

The open-sky bench scene (``scene.open_sky_geometry``: a 200 m ground, a sphere, 50
boxes) from 5 m up; for each visibility, one frame (seed 3, default settings) of the
Livox Mid-40 and of the Ouster OS1-64, both detecting by the LiDAR equation: the share
of the clear-weather frame's surface points that still return, and the false returns
from the air (label ``weather``) as a share of the same count.

    .venv/bin/python bench/realism_chart.py [--out docs]
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

PRESETS = ("livox_mid40", "ouster_os1_64")
VISIBILITIES_M = (20, 35, 50, 75, 100, 150, 200, 300, 500, 1000, 2000, 5000)


def measure(presets=PRESETS, visibilities=VISIBILITIES_M):
    """{preset: {"clear": points, "rows": [(visibility, surface share, false share)]}}."""
    from bench.scene import OPEN_SKY_POSE, open_sky_geometry
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import caster_factory
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.labels import WEATHER_LABEL
    from rls_addon.core.device.presets import get_preset
    from rls_addon.core.scan.settings import ScanSettings

    geometry = open_sky_geometry()
    out = {}
    for pid in presets:
        preset = get_preset(pid)
        scene = PreparedScene(geometry, OPEN_SKY_POSE[:3, 3], preset.range.max_m,
                              caster_factory("auto")[0])
        pattern = preset.pattern()

        def frame(weather=None):
            pts = scan_frame(scene, pattern, OPEN_SKY_POSE, preset,
                             ScanSettings(seed=3, weather=weather), frame=1).points
            air = pts["label"] == WEATHER_LABEL
            return int(np.count_nonzero(~air)), int(np.count_nonzero(air))

        clear = frame()[0]
        rows = []
        for v in visibilities:
            surface, air = frame(f"fog:visibility={v}")
            rows.append((v, surface / clear, air / clear))
        out[pid] = {"name": preset.name, "rays": len(pattern), "clear": clear, "rows": rows}
    return out


def chart(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for (pid, r), colour in zip(res.items(), ("tab:blue", "tab:orange")):
        v = [row[0] for row in r["rows"]]
        ax.plot(v, [100 * row[1] for row in r["rows"]], "-o", color=colour,
                label=f"{r['name']}: surface points ({r['clear']:,} in clear air = 100 %)")
        ax.plot(v, [100 * row[2] for row in r["rows"]], "--s", color=colour, markersize=4,
                label=f"{r['name']}: false returns from the fog")
    ax.set_xscale("log")
    ax.set_xlabel("visibility (m, log scale)")
    ax.set_ylabel("points, % of the clear-weather frame's")
    ax.set_title("Fog: points kept against visibility (open-sky bench scene, sensor 5 m up)")
    ax.grid(alpha=0.3, which="both")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=1)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs"))
    args = ap.parse_args(argv)
    res = measure()
    out = Path(args.out)
    chart(res, out / "realism_fog.png")
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
