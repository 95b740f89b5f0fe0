"""What judging placements by detection costs: RLS's roadside detector and the scoring
of a frame against the frame's scan, and a whole ``rls study --evaluate`` on a sample
scene, each run as a user runs it (``python -m rls_addon`` in subprocesses).

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
        rls("dataset", blend, "--layout", "kitti", "--frames", frames, "--out", tmp / "ds",
            timeout=3600)
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
    scan = statistics.median(scan_s)
    detect = statistics.median(timing["detect_s"])
    vehicle = res["classes"]["vehicle"]["all"]["bev"]["0.5"]
    return {"frames": len(done), "scan_ms": 1000 * scan, "detect_ms": 1000 * detect,
            "score_ms": 1000 * score_s, "learn_s": timing["learn_s"],
            "ratio": (detect + score_s) / scan, "detections": int(len(boxes)),
            "vehicle_ap_r40_bev50": vehicle["ap_r40"],
            "study_s": study_s, "study_candidates": len(report["candidates"]),
            "study_sets_scored": len(report["evaluation"]["sets"]),
            "study_timing_s": report["timing_s"]}


def section(r):
    ok = "**met**" if r["ratio"] <= TARGET else "**missed**"
    return [
        "## Judging placements by detection (issue 30)\n",
        f"The sample intersection, a Pandar64 on 'TL SW' ({r['frames']} frames; "
        "`bench/evaluate_costs.py`). Medians per frame: the scan as `rls scan` reports "
        "it, RLS's roadside detector (`detect_datasets`: foreground, clusters, boxes) and "
        "the scoring (`scoring.score` over every frame, per frame). The background is "
        f"learned once from the frames: {r['learn_s']:.1f} s.\n",
        "| scan | detect | score | (detect + score) / scan | target |",
        "|---|---|---|---|---|",
        f"| {r['scan_ms']:.1f} ms | {r['detect_ms']:.1f} ms | {r['score_ms']:.2f} ms | "
        f"{r['ratio']:.2f}x | <= {TARGET:g}x {ok} |",
        "",
        f"The whole `rls study --device hesai_pandar64 --k 1,2 --pitch 15 --evaluate 1-60:4` "
        f"on the intersection ({r['study_candidates']} candidates, "
        f"{r['study_sets_scored']} sets scored by detection): {r['study_s']:.1f} s wall "
        f"time, of which {r['study_timing_s'].get('scan_s', float('nan')):.1f} s scanning "
        "(each candidate's static scene and its 15 traffic frames, with the detector's "
        "background and foreground).\n",
    ]


def main(argv=None):
    return standalone.main(__doc__, measure, section, argv)


if __name__ == "__main__":
    main()
