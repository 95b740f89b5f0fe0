"""What judging placements by detection costs: RLS's roadside detector and the scoring
of a frame against the frame's scan, the default background (its sweeps of the scene
without road users) against one frame's scan, and a whole ``rls study --evaluate`` on a
sample scene and on a junction built from scratch (``bench/junctions.py``'s cross3),
each run as a user runs it (``python -m rls_addon`` in subprocesses).

Scene: the sample intersection (``sample_scenes/make_scenes.py``) with a Hesai Pandar64
on the traffic-light pole 'TL SW', 15 degrees down into the junction (as
``tests/cli/test_detector_cli.py``). The scan's cost per frame is what ``rls scan``
reports per output (the frame itself); the detector's is ``detect_datasets``' time per
frame (foreground, clusters, boxes; the background is learned once, reported apart);
scoring is ``scoring.score`` over every frame, divided by the frames.

Target: detecting and scoring a frame cost no more than twice scanning it.

    .venv/bin/python -m bench.evaluate_costs [--quick]     (prints JSON, then markdown)
"""

import json
import statistics
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

TARGET = 2.0
MOUNT = r"""
import math, sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.read_factory_settings(use_empty=True)
rls_addon.ensure_registered()
from rls_addon.blender.scenes import build_scene
from rls_addon.blender.scenes.build import mount_position
scene = bpy.context.scene
build_scene("intersection", scene)
x, y, z = mount_position(bpy.data.objects["TL SW"])
lidar = bpy.data.objects.new("L TL SW", None)
lidar.location = (x, y, z)
lidar.rotation_euler = (0.0, math.radians(15.0), math.atan2(-y, -x))
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id = True, "hesai_pandar64"
s.use_sweep_start, s.sweep_start = True, 180.0
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


def measure(quick=False):
    from rls_addon.core.evaluate.detect_dataset import detect_datasets
    from rls_addon.core.evaluate.ground_truth_files import read_ground_truth
    from rls_addon.core.evaluate.scoring import score

    frames = "1-30" if quick else "1-60"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        blend = tmp / "intersection.blend"
        subprocess.run([sys.executable, "-c", MOUNT, str(ROOT), str(blend)], check=True,
                       capture_output=True, timeout=300)
        scanned, _ = rls("scan", blend, "--frames", frames, "--out", tmp / "scan",
                         "--workers", "1", timeout=3600)
        scan_s = [o["seconds"] for o in scanned["outputs"]][1:]  # warm
        dataset, _ = rls("dataset", blend, "--layout", "kitti", "--frames", frames,
                         "--out", tmp / "ds", timeout=3600)
        sweep_s = dataset["background"]["seconds"]
        root = tmp / "ds" / "L_TL_SW"
        boxes, done, timing = detect_datasets([root])
        truth = read_ground_truth(root)
        t = time.perf_counter()
        res = score(truth, boxes, min_points=5)
        score_s = (time.perf_counter() - t) / len(done)
        _, study_s = rls("study", blend, "--device", "hesai_pandar64", "--k", "1,2",
                         "--pitch", "15", "--evaluate", "1-60:4", "--out", tmp / "study",
                         "--workers", "1", timeout=3600)
        report = json.loads((tmp / "study" / "study.json").read_text())
        junction = junction_study(tmp, quick)
    scan = statistics.median(scan_s)
    detect = statistics.median(timing["detect_s"])
    vehicle = res["classes"]["vehicle"]["all"]["bev"]["0.5"]
    return {"frames": len(done), "scan_ms": 1000 * scan, "detect_ms": 1000 * detect,
            "background_sweeps": len(sweep_s), "background_sweep_ms": 1000 * statistics.median(sweep_s),
            "background_ms": 1000 * sum(sweep_s),
            "background_ratio": sum(sweep_s) / scan, "junction": junction,
            "score_ms": 1000 * score_s, "learn_s": timing["learn_s"],
            "ratio": (detect + score_s) / scan, "detections": int(len(boxes)),
            "vehicle_ap_r40_bev50": vehicle["ap_r40"],
            "study_s": study_s, "study_candidates": len(report["candidates"]),
            "study_sets_scored": len(report["evaluation"]["sets"]),
            "study_timing_s": report["timing_s"]}


def junction_study(tmp, quick):
    """The whole ``rls study --evaluate`` on bench/junctions.py's cross3 (its SUMO traffic,
    four corner poles at three pitches, k 1 and 2): wall time and what the study says."""
    from bench.junctions import JUNCTIONS, set_up

    blend = set_up(JUNCTIONS["cross3"], tmp / "cross3")
    evaluate = "1-300:30" if quick else "1-300:10"
    _, wall = rls("study", blend, "--device", "hesai_pandar64", "--k", "1,2", "--pitch",
                  "0:30:15", "--evaluate", evaluate, "--out", tmp / "cross3" / "study",
                  "--workers", "1", timeout=7200)
    report = json.loads((tmp / "cross3" / "study" / "study.json").read_text())
    ev = report["evaluation"]
    aps = [c["ap"] for c in ev["candidates"] if c["ap"] is not None]
    return {"evaluate": evaluate, "study_s": wall, "timing_s": report["timing_s"],
            "candidates": len(ev["candidates"]), "sets": len(ev["sets"]),
            "vehicle_frames": ev["vehicle_frames"], "ap_min": min(aps), "ap_max": max(aps)}


def section(r):
    ok = "**met**" if r["ratio"] <= TARGET else "**missed**"
    j = r["junction"]
    return [
        "## Judging placements by detection (issue 30)\n",
        f"The sample intersection, a Pandar64 on 'TL SW' ({r['frames']} frames; "
        "`bench/evaluate_costs.py`). Medians per frame: the scan as `rls scan` reports "
        "it, RLS's roadside detector (`detect_datasets`: foreground, clusters, boxes) and "
        "the scoring (`scoring.score` over every frame, per frame). The background is "
        "learned once from the dataset's background sweeps (below).\n",
        "| scan | detect | score | (detect + score) / scan | target |",
        "|---|---|---|---|---|",
        f"| {r['scan_ms']:.1f} ms | {r['detect_ms']:.1f} ms | {r['score_ms']:.2f} ms | "
        f"{r['ratio']:.2f}x | <= {TARGET:g}x {ok} |",
        "",
        f"The whole `rls study --device hesai_pandar64 --k 1,2 --pitch 15 --evaluate 1-60:4` "
        f"on the intersection ({r['study_candidates']} candidates, "
        f"{r['study_sets_scored']} sets scored by detection): {r['study_s']:.1f} s wall "
        f"time, of which {r['study_timing_s'].get('scan_s', float('nan')):.1f} s scanning "
        "(each candidate's static scene, its background sweeps and its 15 traffic frames, "
        "with the detector's background and foreground).\n",
        f"The default background (issue 37): {r['background_sweeps']} sweeps of the scene "
        f"with every road user hidden, {r['background_sweep_ms']:.1f} ms each (median), "
        f"{r['background_ms']:.0f} ms in all: {r['background_ratio']:.1f}x one frame's "
        f"scan, once per LiDAR and dataset; learning from them: {r['learn_s']:.2f} s.\n",
        f"The whole `rls study --device hesai_pandar64 --k 1,2 --pitch 0:30:15 --evaluate "
        f"{j['evaluate']}` on `bench/junctions.py`'s cross3 (a signalised junction built "
        f"from scratch with SUMO traffic; {j['candidates']} candidates, {j['sets']} sets "
        f"scored, {j['vehicle_frames']} counted vehicle-frames): {j['study_s']:.0f} s wall "
        f"time, of which {j['timing_s'].get('scan_s', float('nan')):.0f} s scanning; "
        f"candidates' AP {j['ap_min']:.2f} to {j['ap_max']:.2f}.\n",
    ]


def main(argv=None):
    return standalone.main(__doc__, measure, section, argv)


if __name__ == "__main__":
    main()
