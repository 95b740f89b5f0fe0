"""Signalised junctions built from scratch, with SUMO traffic busy enough that queues
stand at red lights, for judging RLS's roadside detector and the placement study away
from the sample scenes (issue 37). Not the sample scenes, and none of their parameters
were tuned here.

- ``cross3``: ``netgenerate``'s single four-way crossing, three car lanes and a sidewalk
  per arm (150 m arms), traffic lights at the centre (junction A0).
- ``skew``: ``tests/fixtures/osm/signal_junction.osm``, a hand-written OpenStreetMap
  junction (a six-lane primary road crossed at 70 degrees by a four-lane secondary one,
  signals at the crossing node), converted by ``netconvert`` as docs/roads.md says.
- ``tee``: ``tests/fixtures/osm/signal_tee.osm``, a hand-written signalised T-junction
  (four lanes and two); held out: built after the detector's rules were chosen on the
  other two and the sample scenes, and measured once.

Each is made as a user makes a scene: the network, ``rls scene from-net --junction
--origin junction``, ``rls traffic generate`` (random trips at ``rate`` vehicles per hour,
with pedestrians), ``rls traffic import`` of a window of the run, and a Hesai Pandar64 on
a corner pole pitched 15 degrees down into the junction (as issue 37's trials). The scene
runs at SUMO's step (10 frames a second), as ``rls scene from-net`` makes it.

    .venv/bin/python -m bench.junctions [--quick] [--keep DIR]   (prints JSON, then markdown)
"""

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

OSM = ROOT / "tests" / "fixtures" / "osm"
OSM_OPTIONS = ("--osm.sidewalks", "--osm.crossings", "--sidewalks.guess", "--crossings.guess",
               "--junctions.corner-detail", "5", "--default.sidewalk-width", "2",
               "--default.crossing-width", "4")


@dataclass(frozen=True)
class Junction:
    name: str
    junction: str       # the signalised junction's id in the network
    mount: str          # the pole the LiDAR is put on
    rate: float         # vehicles per hour, random trips
    duration: float     # seconds of SUMO run
    begin: float        # the window imported: [begin, end] seconds of the run
    end: float
    seed: int = 1
    osm: str = None     # an OpenStreetMap file of tests/fixtures/osm (else netgenerate's)
    held_out: bool = False  # no detector parameter was chosen by looking at it

    def network(self, folder):
        """The SUMO network file, made in ``folder``."""
        out = Path(folder) / f"{self.name}.net.xml"
        if self.osm is None:
            sumo_tool("netgenerate", "--grid", "--grid.x-number", "1", "--grid.y-number", "1",
                      "--grid.attach-length", "150", "--default.lanenumber", "3",
                      "--tls.set", "A0", "--sidewalks.guess", "--crossings.guess", "-o", out)
        else:
            sumo_tool("netconvert", "--osm-files", OSM / self.osm, *OSM_OPTIONS, "-o", out)
        return out


JUNCTIONS = {
    "cross3": Junction("cross3", "A0", "Pole SW A0", rate=3600, duration=240, begin=150,
                       end=180),
    "skew": Junction("skew", "1", "Pole SW 1", rate=3600, duration=240, begin=150, end=180,
                     osm="signal_junction.osm"),
    "tee": Junction("tee", "1", "Pole SW 1", rate=3600, duration=240, begin=150, end=180,
                    osm="signal_tee.osm", held_out=True),
}

MOUNT = r"""
import math, sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
rls_addon.ensure_registered()
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
import numpy as np
from rls_addon.blender.scenes.build import mount_position
scene = bpy.context.scene
region = bpy.data.objects["InfraLOB"]
corners = np.array([tuple(region.matrix_world @ v.co) for v in region.data.vertices])
cx, cy = corners[:, :2].mean(0)
for mount in filter(None, sys.argv[4].split(",")):
    x, y, z = mount_position(bpy.data.objects[mount])
    lidar = bpy.data.objects.new("L " + mount, None)
    lidar.location = (x, y, z)
    lidar.rotation_euler = (0.0, math.radians(15.0), math.atan2(cy - y, cx - x))
    scene.collection.objects.link(lidar)
    s = lidar.rls_lidar
    s.is_lidar, s.preset_id = True, "hesai_pandar64"
    s.use_sweep_start, s.sweep_start = True, 180.0  # the seam behind the pole
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
"""


def sumo_tool(name, *args):
    import sumo

    env = dict(os.environ, SUMO_HOME=sumo.SUMO_HOME)
    proc = subprocess.run([os.path.join(sumo.SUMO_HOME, "bin", name), *map(str, args)],
                          env=env, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"{name} failed: {proc.stderr[-2000:]}")


def run_rls(*args, timeout=7200):
    """(stdout, stderr, wall seconds) of ``python -m rls_addon ARGS``; raises on failure."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "rls_addon", *map(str, args)], env=env,
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"rls {' '.join(map(str, args[:2]))} failed: {proc.stderr[-2000:]}")
    return proc.stdout, proc.stderr, time.perf_counter() - t


def set_up(spec, folder, mounts=None):
    """The junction's scene with its traffic and LiDAR(s) on ``mounts`` (default: its
    mount), as ``folder/<name>.blend``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    net = spec.network(folder)
    roads = folder / f"{spec.name}_roads.blend"
    run_rls("scene", "from-net", net, "--junction", spec.junction, "--origin", "junction",
            "--out", roads, "--overwrite")  # at SUMO's step: 10 frames a second
    fcd = folder / f"{spec.name}.fcd.xml"
    run_rls("traffic", "generate", net, "--duration", spec.duration, "--rate", spec.rate,
            "--seed", spec.seed, "--out", fcd, "--overwrite")
    traffic = folder / f"{spec.name}_traffic.blend"
    run_rls("traffic", "import", roads, "--fcd", fcd, "--begin", spec.begin, "--end",
            spec.end, "--out", traffic, "--overwrite")
    blend = folder / f"{spec.name}.blend"
    subprocess.run([sys.executable, "-c", MOUNT, str(ROOT), str(traffic), str(blend),
                    ",".join(mounts or [spec.mount])],
                   check=True, capture_output=True, timeout=600)
    return blend


def sensor_dir(mount):
    return "L_" + mount.replace(" ", "_")


def detection(spec, blend, folder, frames):
    """rls dataset -> rls detect -> rls evaluate (vehicles and pedestrians with 50+
    points in the InfraLOB) on ``frames``; the evaluation's result and timings."""
    folder = Path(folder)
    ds, det, res = folder / "ds", folder / "det", folder / "result.json"
    _, _, dataset_s = run_rls("dataset", blend, "--layout", "kitti", "--frames", frames,
                              "--out", ds, "--overwrite")
    root = ds / sensor_dir(spec.mount)
    out, _, detect_s = run_rls("detect", root, "--out", det, "--overwrite")
    run_rls("evaluate", "--truth", root, "--detections", det, "--lob", f"{blend}:InfraLOB",
            "--min-points", "50", "--out", res, "--overwrite")
    return json.loads(res.read_text()), {"dataset_s": dataset_s, "detect_s": detect_s,
                                          "detect_stdout": out}


def figures(result):
    """The headline numbers of an evaluation: per class at BEV IoU 0.5 and 0.3, recall,
    precision, APs, and standing and moving apart."""
    out = {}
    for cls in ("vehicle", "pedestrian", "cyclist"):
        for thr in ("0.5", "0.3"):
            r = result["classes"][cls]["all"]["bev"][thr]
            by = r.get("by_motion", {})
            out[f"{cls}_{thr}"] = {
                "gt": r["gt"], "tp": r["tp"], "fp": r["fp"],
                "recall": r["tp"] / r["gt"] if r["gt"] else None,
                "precision": r["tp"] / (r["tp"] + r["fp"]) if r["tp"] + r["fp"] else None,
                "ap_r40": r["ap_r40"], "ap_r40_kitti": r.get("ap_r40_kitti"),
                "standing": by.get("standing"), "moving": by.get("moving")}
    v = out["vehicle_0.5"]
    st, mv = v["standing"] or {"gt": 0}, v["moving"] or {"gt": 0}
    v["standing_share"] = st["gt"] / (st["gt"] + mv["gt"]) if st["gt"] + mv["gt"] else None
    return out


def study(blend, folder, evaluate, k="1,2", pitch="0:30:15"):
    """``rls study --evaluate`` on the junction's mounts; its study.json and wall time."""
    out = Path(folder) / "study"
    _, stderr, took = run_rls("study", blend, "--device", "hesai_pandar64", "--k", k,
                              "--pitch", pitch, "--evaluate", evaluate, "--out", out,
                              "--overwrite")
    return json.loads((out / "study.json").read_text()), took, stderr


def measure(quick=False, keep=None):
    frames = "1-300:5" if quick else "1-300:2"
    evaluate = "1-300:20" if quick else "1-300:10"
    numbers = {}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(keep or tmp)
        for name, spec in JUNCTIONS.items():
            folder = base / name
            blend = set_up(spec, folder)
            res, timing = detection(spec, blend, folder, frames)
            got = figures(res)
            got.update(frames=frames, dataset_s=timing["dataset_s"],
                       detect_s=timing["detect_s"])
            report, study_s, _ = study(blend, folder, evaluate)
            got["study"] = {"seconds": study_s, "evaluate": evaluate,
                            "evaluation": summary_of(report)}
            numbers[name] = got
    return numbers


def summary_of(report):
    """What the docs tell of a study: AP per candidate and set, per k, and the
    correlations pooled and within k."""
    ev = report["evaluation"]
    return {"aps": [c["ap"] for c in ev["candidates"]],
            "sets": [[s["sensors"], s["ap"]] for s in ev["sets"]],
            "best_by_ap": ev["best_by_ap"], "correlation": ev["correlation"],
            "correlation_by_k": ev.get("correlation_by_k"),
            "vehicle_frames": ev.get("vehicle_frames"), "background": ev.get("background")}


def section(r):
    lines = ["## Detection on junctions built from scratch (issue 37)\n",
             "Two signalised junctions (`bench/junctions.py`), SUMO traffic, a Pandar64 on "
             "a corner pole 15 degrees down; vehicles and pedestrians with 50+ points in "
             "the InfraLOB at BEV IoU 0.5 (pedestrians also 0.3).\n",
             "| junction | standing share | vehicle recall (standing / moving) | vehicle "
             "precision | pedestrian recall 0.3 / 0.5 | study (s) |",
             "|---|---|---|---|---|---|"]
    for name, got in r.items():
        v, p3, p5 = got["vehicle_0.5"], got["pedestrian_0.3"], got["pedestrian_0.5"]
        st, mv = v["standing"], v["moving"]
        lines.append(
            f"| {name} | {v['standing_share']:.2f} | {v['recall']:.3f} "
            f"({st['recall'] if st['recall'] is None else round(st['recall'], 3)} / "
            f"{mv['recall'] if mv['recall'] is None else round(mv['recall'], 3)}) | "
            f"{v['precision']:.3f} | {fmt(p3['recall'])} / {fmt(p5['recall'])} | "
            f"{got['study']['seconds']:.0f} |")
    return lines


def fmt(v):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.3f}"


def main(argv=None):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--keep", help="build the junctions in this folder and keep them")
    a = ap.parse_args(argv)
    numbers = measure(a.quick, a.keep)
    print(json.dumps(numbers, indent=1, default=float))
    print("\n".join(section(numbers)))
    return numbers


if __name__ == "__main__":
    main()
