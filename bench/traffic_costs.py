"""What importing SUMO traffic costs against the SUMO run that made it (issue 33): a
busy hour (at least 1,000 vehicles) over a small network, ``rls traffic generate``
(random trips, SUMO with FCD output every 0.1 s), then ``rls traffic import`` of the
whole hour into an empty scene at 10 frames per second, each run as a user runs it
(``python -m rls_addon`` in subprocesses; the import's time includes starting Blender
and saving the .blend). The FCD read alone (``core.traffic.fcd.load``) is timed in this
process.

Network: SUMO's ``netgenerate --grid`` 3 x 3 junctions 100 m apart (12 two-way roads of
one lane each way), no pedestrians, ``--rate 1200`` vehicles per hour, seed 1.

    .venv/bin/python -m bench.traffic_costs [--quick]     (prints JSON, then markdown)
"""

import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import standalone  # noqa: E402 - after the path above
from bench.commands import rls  # noqa: E402

EMPTY = r"""
import sys, bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.render.fps = 10
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
"""


def measure(quick=False):
    from rls_addon.core.traffic.fcd import load
    from rls_addon.core.traffic.sumo_run import binary, sumo_home

    duration, rate = (600, 1200) if quick else (3600, 1200)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        net = tmp / "grid.net.xml"
        subprocess.run([binary(sumo_home(), "netgenerate"), "--grid", "--grid.number", "3",
                        "--grid.length", "100", "-o", str(net)], check=True,
                       capture_output=True)
        blend = tmp / "empty.blend"
        subprocess.run([sys.executable, "-c", EMPTY, str(blend)], check=True,
                       capture_output=True, timeout=300)
        fcd = tmp / "hour.xml"
        gen, gen_s = rls("traffic", "generate", net, "--duration", duration, "--rate", rate,
                          "--seed", 1, "--pedestrians", "no", "--out", fcd)
        t = time.perf_counter()
        data, _ = load(str(fcd))
        read_s = time.perf_counter() - t
        samples = sum(len(tr.times) for tr in data.tracks.values())
        del data
        imp, import_s = rls("traffic", "import", blend, "--fcd", fcd, "--out",
                             tmp / "hour.blend")
        size_mb = fcd.stat().st_size / 1e6
    return {"duration_s": duration, "rate_veh_h": rate, "vehicles": imp["vehicle"]
            + imp["cyclist"], "objects": imp["objects"], "frames": imp["frames"],
            "object_frames": imp["object_frames"], "fcd_samples": samples,
            "fcd_mb": size_mb, "trips_s": gen["trips_s"], "sumo_s": gen["sumo_s"],
            "generate_s": gen_s, "read_s": read_s, "import_s": import_s,
            "ratio_import_sumo": import_s / gen["sumo_s"],
            "ratio_import_generate": import_s / gen_s}


def section(r):
    return [
        "## SUMO traffic: import against the SUMO run (issue 33)\n",
        f"A busy {r['duration_s'] / 3600:g} h on a 3 x 3 grid (`bench/traffic_costs.py`): "
        f"`rls traffic generate --rate {r['rate_veh_h']:g}` made {r['vehicles']} vehicles "
        f"({r['fcd_samples']:,} FCD samples every 0.1 s, {r['fcd_mb']:.0f} MB); "
        f"`rls traffic import` keyed {r['objects']} objects over {r['frames']:,} frames "
        f"at 10 fps ({r['object_frames']:,} object-frames).\n",
        "| random trips | SUMO run | generate (all) | FCD read | import (all) | "
        "import / SUMO run | import / generate |",
        "|---|---|---|---|---|---|---|",
        f"| {r['trips_s']:.1f} s | {r['sumo_s']:.1f} s | {r['generate_s']:.1f} s | "
        f"{r['read_s']:.1f} s | {r['import_s']:.1f} s | {r['ratio_import_sumo']:.2f}x | "
        f"{r['ratio_import_generate']:.2f}x |",
        "",
    ]


def main(argv=None):
    return standalone.main(__doc__, measure, section, argv)


if __name__ == "__main__":
    main()
