"""RLS benchmarks: ray-casting backends, frame times, scaling, memory, and a
speed-against-accuracy chart. Writes docs/benchmarks.md and docs/bench_*.png.

    .venv/bin/python bench/run.py [--out docs] [--quick]

Every number comes from this one run on this machine. Times are the best of a few
repeats (the machine may be shared); rays/s count every ray cast, hit or miss.
Baselines on the same rays and triangles: the bare ``BVHTree.ray_cast`` Python loop
and Open3D's ``RaycastingScene.cast_rays``.

This module only runs the sections and writes the report (``bench/report.py``). Each
section is a module of its own with its ``measure`` and the report's lines of it
(``section``): in the order measured, devices, scaling, engine_costs, blender_scan,
frame_costs, drive_costs, effect_costs, memory, tessellation, scale_out,
realism_chart, study_costs, evaluate_costs, traffic_costs, live_costs and long_runs
(those with a ``main`` also run alone: ``python -m bench.<name> [--quick]``).
"""

import argparse
import gc
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.machine import machine_info  # noqa: E402
from bench.timing import log  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs"))
    ap.add_argument("--quick", action="store_true", help="smaller series (for a smoke run)")
    ap.add_argument("--json", default=str(ROOT / "build" / "bench" / "results.json"),
                    help="raw numbers are written here first (default build/bench/)")
    ap.add_argument("--from-json", help="only rewrite the report and charts from raw numbers")
    args = ap.parse_args()
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        sys.exit("bench: matplotlib is missing: pip install matplotlib (see requirements)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.from_json:
        res = json.loads(Path(args.from_json).read_text())
    else:
        res = measure(args.quick)
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(res, indent=1, default=float))
    from bench import engine_costs, scaling, tessellation
    from bench.report import write_report

    charts = {"scaling": "bench_scaling.png", "tessellation": "bench_tessellation.png"}
    scaling.chart(res["triangles"], res["rays"], out / charts["scaling"])
    tessellation.chart(res["tessellation"], out / charts["tessellation"], "Pandar64")
    charts["motion"] = "bench_motion_substeps.png"
    charts["disks"] = "bench_infranuc_disks.png"
    engine_costs.chart_motion(res["costs"]["motion"]["embree"], out / charts["motion"])
    engine_costs.chart_disks(res["costs"]["disks"], out / charts["disks"])
    if res["costs"].get("drive_costs"):
        from bench import drive_costs

        drive_costs.chart(res["costs"]["drive_costs"], out / drive_costs.CHART)
    if res["costs"].get("fog"):
        from bench import realism_chart

        realism_chart.chart(res["costs"]["fog"], out / "realism_fog.png")
    r = write_report(out / "benchmarks.md", res["machine"], res["devices"], res["triangles"],
                     res["rays"], res["memory"], res["tessellation"], res["pattern_s"],
                     charts, res["hooks"], res["seconds"], res["costs"])
    print(json.dumps({"report": str(out / "benchmarks.md"), "ratios": r,
                      "minutes": round(res["seconds"] / 60, 1)}))
    log(f"bench: done in {res['seconds'] / 60:.1f} min: {out / 'benchmarks.md'}")


def measure(quick):
    from rls_addon.core.casting import embree as embree_caster

    if not embree_caster.available():
        sys.exit("bench: embreex is missing (" + embree_caster.unavailable_reason() + ")")
    from bench.machine import require_compiled_loop

    require_compiled_loop()
    import bpy  # noqa: F401

    from bench import blender_scan, devices, engine_costs, memory, scaling, tessellation
    from bench.scene import SENSOR_POSE, street_geometry

    from rls_addon.core.world.bodies import PreparedScene

    # Every frame timed here is cold: repeats of a frame would otherwise reuse the static
    # cast of the one before (a still sensor's frames do, see PreparedScene.cast), and a
    # best-of-N would time that. Rows that time the reuse say so and switch it on.
    PreparedScene.reuse_casts = False
    t_start = time.perf_counter()
    info = machine_info()
    log(f"bench: {info['cpu']}, {info['cores']} cores")
    g = street_geometry(1_000_000)
    dev = devices.measure(g, SENSOR_POSE, quick)
    p64, _ = devices.preset_or_fallback("Pandar64", "hesai_pandar64")
    p128, _ = devices.preset_or_fallback("Pandar128", "hesai_pandar128")
    pattern_s = min(devices.fresh_pattern_time(p128) for _ in range(3))
    ray_rows = scaling.rays(g, SENSOR_POSE, p64, quick)
    hooks = {"ghosting cost": dev["ghosting"]}
    costs = engine_costs.measure(g, SENSOR_POSE, p64, quick)
    log("bench: a still lidar in Blender (scene extraction included)")
    costs["blender"] = blender_scan.measure(g, SENSOR_POSE)
    log("bench: a frame against its cast, open sky and street (bench/frame_costs.py)")
    from bench import frame_costs

    costs["frame_costs"] = frame_costs.measure(street=g, quick=quick)
    log("bench: moving sensors against their casts, the traffic drive with boxes and the "
        "open sky (bench/drive_costs.py)")
    from bench import drive_costs

    costs["drive_costs"] = drive_costs.measure(quick=quick)
    log("bench: beam footprints and fog against the clear frame (bench/effect_costs.py)")
    from bench import effect_costs

    costs["effect_costs"] = effect_costs.measure(quick=quick, street=g)
    del g
    gc.collect()
    tri_rows = scaling.triangles(SENSOR_POSE, p64, quick)
    mem = memory.measure([100_000, 1_000_000] if quick else [100_000, 1_000_000, 4_000_000])
    levels = [8, 16, 32, 64, 128, 256] if quick else [8, 16, 32, 64, 128, 256, 512]
    tess = tessellation.measure(p64, levels)
    log("bench: scale-out, rls dataset and rls study on 1 and 2 Dask workers (bench/scale_out.py)")
    from bench import scale_out

    costs["scale_out"] = scale_out.measure(repeat=1 if quick else 2)
    log("bench: points kept in fog against visibility (bench/realism_chart.py)")
    from bench import realism_chart

    costs["fog"] = realism_chart.measure()
    log("bench: a study candidate against its cast (bench/study_costs.py)")
    from bench import study_costs

    costs["study_costs"] = study_costs.measure(quick)
    log("bench: detection and scoring against the scan, rls study --evaluate "
        "(bench/evaluate_costs.py)")
    from bench import evaluate_costs

    costs["evaluate_costs"] = evaluate_costs.measure(quick)
    log("bench: a busy hour of SUMO traffic imported against its SUMO run "
        "(bench/traffic_costs.py)")
    from bench import traffic_costs
    from rls_addon.core.traffic.sumo_run import SumoMissing

    try:
        costs["traffic_costs"] = traffic_costs.measure(quick)
    except SumoMissing as exc:  # the section is left out
        log(f"bench: SUMO traffic skipped: {exc}")
    log("bench: live coverage: a moved LiDAR's update, a drag's scans (bench/live_costs.py)")
    from bench import live_costs

    costs["live_costs"] = live_costs.measure(quick)
    log("bench: long runs: memory, stalls, Bezier keyframes (bench/long_runs.py)")
    from bench import long_runs

    costs["long_runs"] = long_runs.measure(quick)
    info["loadavg_end"] = os.getloadavg()[0]
    return {"machine": info, "devices": dev, "triangles": tri_rows, "rays": ray_rows,
            "memory": mem, "tessellation": tess, "pattern_s": pattern_s, "hooks": hooks,
            "costs": costs, "seconds": time.perf_counter() - t_start}


if __name__ == "__main__":
    main()
