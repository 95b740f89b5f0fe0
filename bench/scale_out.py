"""Scale-out benchmark: `rls dataset` and `rls study` on one worker against two (a Dask
LocalCluster), run as a user runs them, and what the measurements say about more
workers. The numbers behind docs/scale.md ("What to expect").

    .venv/bin/python bench/scale_out.py [--out DIR] [--repeat 2] [--quiet-wait S]

Writes DIR/scale_out.json (raw numbers) and DIR/scale_out.md (the section
bench/run.py puts into docs/benchmarks.md); default DIR is build/bench. Takes about
3 minutes on the project's 2-core machine.

Each command runs in a subprocess (`python -m rls_addon ...`); runs with 1 and 2 workers
alternate, best of ``--repeat`` wall times; next to each run the load average before it
and the cores other work kept busy during it (/proc/stat less the command's own CPU).

* Throughput of `rls dataset --layout kitti` (frames/s) and `rls study`
  (candidates/s) with `--workers 1` (in-process) and `--workers 2`, and the ratio.
* Where the 2-worker run's time goes, from its stderr lines stamped as they arrive:
  pieces handed out (command start, scene, cluster up), pieces back, the tail after
  the last (split files; the study's search and report). Worker start-up (import
  bpy, open the scene) is measured apart, by the same command with pieces of one
  scan or one candidate. From these an Amdahl-style estimate for N workers on N
  cores: serial part + worker start-up + parallel part / N.
* That the 2-worker outputs are the 1-worker ones: sha256 of every file (the study's
  timing columns and fields set aside).
* What the 1-worker runs say about the cost model of ``--workers auto``
  (``rls_addon/core/scan/dask_run.py``).
"""

import argparse
import csv
import datetime
import hashlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# The sample intersection (its traffic driving through it over frames 1-60) with six
# LiDARs: two Pandar64 and an OS1-64 on traffic-light poles looking into the junction,
# two VLP-16 and a VLP-32C on the roofs of three of the cars.
SCENE_SCRIPT = r"""
import math, sys
import bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.read_factory_settings(use_empty=True)
rls_addon.register()
from rls_addon.blender.scenes import build_scene
from rls_addon.blender.scenes.build import lidar_object, mount_position
build_scene("intersection", bpy.context.scene)
scene = bpy.context.scene
def lidar(name, preset, **kw):
    return lidar_object(scene, name, preset, seed=7, **kw)
lidar("Pole NE", "hesai_pandar64", location=mount_position(bpy.data.objects["TL NE"]),
      rotation=(0, math.radians(10), math.radians(-135)))
lidar("Pole SW", "hesai_pandar64", location=mount_position(bpy.data.objects["TL SW"]),
      rotation=(0, math.radians(10), math.radians(45)))
lidar("Pole NW", "ouster_os1_64", location=mount_position(bpy.data.objects["TL NW"]),
      rotation=(0, math.radians(10), math.radians(-45)))
lidar("Roof west", "velodyne_vlp16", parent=bpy.data.objects["Car west"], location=(0, 0, 2.0))
lidar("Roof east", "velodyne_vlp16", parent=bpy.data.objects["Car east"], location=(0, 0, 2.0))
lidar("Roof north", "velodyne_vlp32c", parent=bpy.data.objects["Car north"],
      location=(0, 0, 2.0))
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""
# The LiDARs' devices (for the rays the cost model of `--workers auto` counts).
DEVICES = {"Pole NE": "hesai_pandar64", "Pole SW": "hesai_pandar64", "Pole NW": "ouster_os1_64",
           "Roof west": "velodyne_vlp16", "Roof east": "velodyne_vlp16",
           "Roof north": "velodyne_vlp32c"}
SCENE_TEXT = ("the sample intersection (`rls_addon/blender/scenes`, its traffic driving "
              "through it over frames 1-60) with six LiDARs: two Pandar64 and an OS1-64 on "
              "traffic-light poles, two VLP-16 and a VLP-32C on the roofs of three cars "
              "(`bench/scale_out.py`)")
FRAMES = "1-60"
DATASET = ["--layout", "kitti", "--frames", FRAMES]
# Every mount of the intersection (4 traffic lights, 4 street lights) at 5 pitches and
# 3 yaws, each candidate scanned over the static scene and 6 frames of traffic.
STUDY = ["--device", "hesai_pandar64", "--k", "1,2", "--pitch", "0:40:10", "--yaw=-20:20:20",
         "--traffic", "1-60:10"]
# The same commands with pieces of one scan (the first frame) or one candidate: how long
# two workers take to start (import bpy, open the scene; the study's prepare its scanner).
PROBES = {"dataset": ["--layout", "kitti", "--frames", FRAMES.split("-")[0]],
          "study": ["--device", "hesai_pandar64", "--k", "1", "--mount", "TL NE", "--pitch",
                    "0", "--traffic", "1-60:10"]}
TARGET = 1.7
STUDY_TIMING_COLUMNS = {"scan_seconds"}
STUDY_TIMING_KEYS = {"seconds", "per_candidate_s", "scan_seconds", "timing_s", "report", "files"}


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def load():
    return round(os.getloadavg()[0], 2)


def busy_seconds():
    """CPU seconds every core of the machine has spent busy so far (/proc/stat)."""
    try:
        with open("/proc/stat") as f:
            v = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return None
    return (sum(v[:8]) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")  # all but idle, iowait


def children_seconds():
    """CPU seconds of this process's finished children and theirs (the command's workers)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def others(seconds=1.0):
    """Cores other work keeps busy, over the next ``seconds``."""
    b0 = busy_seconds()
    time.sleep(seconds)
    b1 = busy_seconds()
    return None if b0 is None else round(max(0.0, b1 - b0) / seconds, 2)


def wait_quiet(max_wait, threshold=0.2):
    """Wait up to ``max_wait`` seconds for other work to use under ``threshold`` cores."""
    t_end = time.perf_counter() + max_wait
    while True:
        got = others()
        if got is None or got < threshold or time.perf_counter() >= t_end:
            return got


def build_scene(path):
    proc = subprocess.run([sys.executable, "-c", SCENE_SCRIPT, str(ROOT), str(path)],
                          check=False, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError("bench: building the scale-out scene failed:\n" + proc.stderr[-3000:])


def run_cli(args, quiet_wait=0.0):
    """Run ``python -m rls_addon ARGS`` as a user does; every stderr line stamped with
    its arrival time (s since launch). Returns the wall time, the lines, the JSON
    summary, the load average before, the cores other work kept busy just before
    and during the run (the machine's busy CPU time less the command's own)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    before = wait_quiet(quiet_wait)
    load_before = load()
    b0, c0 = busy_seconds(), children_seconds()
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "rls_addon", *map(str, args)], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []

    def read_stderr():
        for line in proc.stderr:
            lines.append((time.perf_counter() - t0, line.rstrip("\n")))

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    stdout = proc.stdout.read()
    proc.wait()
    wall = time.perf_counter() - t0
    b1, c1 = busy_seconds(), children_seconds()
    reader.join()
    if proc.returncode != 0:
        raise RuntimeError(f"bench: rls {' '.join(map(str, args[:1]))} failed "
                           f"({proc.returncode}):\n" + "\n".join(ln for _, ln in lines[-30:]))
    start = stdout.find("{")
    summary = json.JSONDecoder().raw_decode(stdout[start:])[0] if start >= 0 else {}
    during = None if b0 is None else round(max(0.0, (b1 - b0) - (c1 - c0)) / wall, 2)
    return {"wall_s": wall, "lines": lines, "summary": summary, "load_before": load_before,
            "others_before": before, "others_during": during, "own_cpu_s": c1 - c0}


# ---- the outputs of one run against another --------------------------------------------

def _digest(path, kind):
    data = path.read_bytes()
    if kind == "study" and path.name == "candidates.csv":
        rows = list(csv.DictReader(io.StringIO(data.decode())))
        keep = [c for c in (rows[0].keys() if rows else []) if c not in STUDY_TIMING_COLUMNS]
        data = json.dumps([[r[c] for c in keep] for r in rows]).encode()
    elif kind == "study" and path.suffix == ".json":
        def strip(v):
            if isinstance(v, dict):
                return {k: strip(x) for k, x in v.items() if k not in STUDY_TIMING_KEYS}
            if isinstance(v, list):
                return [strip(x) for x in v]
            return v
        data = json.dumps(strip(json.loads(data)), sort_keys=True).encode()
    return hashlib.sha256(data).hexdigest()


def tree_digests(folder, kind):
    folder = Path(folder)
    return {str(p.relative_to(folder)): _digest(p, kind)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def compare(a, b, kind):
    da, db = tree_digests(a, kind), tree_digests(b, kind)
    differ = sorted(k for k in set(da) | set(db) if da.get(k) != db.get(k))
    return {"files": len(da), "identical": not differ and bool(da), "differ": differ[:10],
            "digest": hashlib.sha256(json.dumps(sorted(da.items())).encode()).hexdigest()[:16]}


# ---- where the time of a 2-worker run goes ----------------------------------------------

def handed_out(lines):
    """(seconds since launch, pieces) of the line a sharded run prints when it has
    handed its pieces to the workers."""
    for t, ln in lines:
        m = re.match(r"rls: (\d+) (pieces|candidate blocks) on", ln)
        if m:
            return t, int(m.group(1))
    return None, 0


def completions(lines, pieces):
    """Arrival times of finished pieces. A dataset piece prints one ``[i/n] ... (host:pid)``
    line; a study block of ``ceil(n / pieces)`` candidates one line per candidate, all
    at once when the block is back."""
    marks = [(t, ln) for t, ln in lines if ln.startswith("[")]
    if len(marks) == pieces:
        return [t for t, _ in marks]
    total = int(re.match(r"\[\d+/(\d+)\]", marks[-1][1]).group(1)) if marks else 0
    size = -(-total // max(1, pieces))
    return [marks[min(len(marks), k + size) - 1][0] for k in range(0, len(marks), size)]


def startup(run):
    """Worker start-up: from the pieces handed out to the first piece back, in a run
    whose pieces are one scan (the dataset's first frame) or one candidate."""
    handed, pieces = handed_out(run["lines"])
    done = completions(run["lines"], pieces)
    return done[0] - handed if handed is not None and done else None


def breakdown(run, workers, worker_startup):
    """Serial part, worker start-up, parallel part and per-shard cost of a run on
    ``workers`` workers, from its stderr times (see the module's docstring). The
    parallel part counts the workers busy from start-up to the last piece back (a
    worker waiting for the last piece of the other counts as busy)."""
    lines = run["lines"]
    handed, pieces = handed_out(lines)
    done = completions(lines, pieces)
    if handed is None or not done or worker_startup is None:
        return None
    tail = run["wall_s"] - done[-1]
    parallel = workers * max(0.0, done[-1] - handed - worker_startup)
    serial = handed + tail
    return {"pieces": pieces, "handed_out_s": handed, "first_piece_s": done[0],
            "last_piece_s": done[-1], "shard_s": parallel / pieces,
            "worker_startup_s": worker_startup, "tail_s": tail, "serial_s": serial,
            "parallel_s": parallel, "wall_s": run["wall_s"],
            "done_s": [round(t, 3) for t in done]}


def estimate(serial_run_s, b, workers=(1, 2, 4, 8, 16)):
    """T(N) = serial + worker start-up + parallel / N, on N cores as fast as these;
    N = 1 is the measured in-process run (no cluster)."""
    out = []
    for n in workers:
        t = serial_run_s if n == 1 else b["serial_s"] + b["worker_startup_s"] + b["parallel_s"] / n
        out.append({"workers": n, "seconds": t, "speedup": serial_run_s / t})
    limit = serial_run_s / (b["serial_s"] + b["worker_startup_s"])
    return out, limit


# ---- the cost model of --workers auto ----------------------------------------------------

def cost_model(dataset_summary, study_summary, traffic_frames):
    """What the in-process runs say about ``core.scan.dask_run``'s serial cost model
    (seconds per scan + seconds per ray), against what the model estimates. The
    dataset's steps time each scan (``seconds``); the rest of the run (frame changes,
    ground truth, files) is the per-scan overhead. Rays are counted as
    ``commands.distribute`` counts them (the pattern's rays per scan)."""
    from rls_addon.core.scan import dask_run
    from rls_addon.core.device.presets import get_preset

    frames = dataset_summary["frames"]
    rays = sum(len(get_preset(DEVICES[n]).pattern(frames[0])) for n in dataset_summary["sensors"])
    rays *= len(frames)
    scans = dataset_summary["scanned"]
    scan_s = sum(o["seconds"] for o in dataset_summary["outputs"])
    run_s = dataset_summary["seconds"]
    study_scans = study_summary["candidates"] * (1 + traffic_frames)
    study_rays = len(get_preset(STUDY[STUDY.index("--device") + 1]).pattern()) * study_scans
    study_s = study_summary["timing_s"]["scan_s"]

    return {"dataset": {"scans": scans, "rays": rays, "run_s": run_s, "scan_s": scan_s,
                        "per_scan_s": (run_s - scan_s) / scans, "per_ray_s": scan_s / rays,
                        "model_s": dask_run.model_seconds(scans, rays)},
            "study": {"scans": study_scans, "rays": study_rays, "run_s": study_s,
                      "per_scan_s": study_s / study_scans, "per_ray_s": study_s / study_rays,
                      "model_s": dask_run.model_seconds(study_scans, study_rays)},
            "constants": {"SECONDS_PER_SCAN": dask_run.SECONDS_PER_SCAN,
                          "SECONDS_PER_RAY": dask_run.SECONDS_PER_RAY,
                          "AUTO_MIN_SECONDS": dask_run.AUTO_MIN_SECONDS}}


def break_even(d):
    """Work in one process (s) above which 2 workers beat one process, and above which
    they are 1.3x faster, from the dataset's Amdahl fit: T(1) = s1 + P and
    T(2) = fixed2 + k P / 2, where s1 is the one-process run's time besides its work P,
    fixed2 the 2-worker run's serial part and worker start-up, and k the work the two
    workers did (pieces x per shard) over P; 2 / k bounds the speed-up of 2 workers."""
    b = d["breakdown"]
    if not b:
        return None
    work = d["serial_work_s"]
    s1 = d["runs"]["1"]["wall_s"] - work
    fixed2 = b["serial_s"] + b["worker_startup_s"]
    k = b["parallel_s"] / work

    def above(x):  # s1 + P >= x (fixed2 + k P / 2)
        return max(0.0, (x * fixed2 - s1) / (1 - x * k / 2)) if x * k < 2 else float("inf")

    return {"serial_fixed_s": s1, "two_worker_fixed_s": fixed2, "work_ratio": k,
            "break_even_s": above(1.0), "x1_3_s": above(1.3), "x1_7_s": above(TARGET),
            "bound": 2 / k}


# ---- the measurement --------------------------------------------------------------------

def measure(workdir=None, repeat=2, quiet_wait=0.0):
    """Every number of the section; ``workdir`` keeps the scene and the outputs (default:
    a temporary folder, removed). Runs of one command alternate between 1 and 2 workers,
    so both see the same conditions; ``quiet_wait``: seconds to wait, at most, before
    each run for other work to use under 0.2 cores."""
    import tempfile

    t_start = time.perf_counter()
    date = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    own = workdir is None
    workdir = Path(tempfile.mkdtemp(prefix="rls-scale-out-") if own else workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    scene = workdir / "intersection_4lidars.blend"
    res = {"date": date, "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
           else os.cpu_count(), "repeat": repeat, "load_start": load(), "scene": SCENE_TEXT,
           "dataset_args": DATASET, "study_args": STUDY}
    build_scene(scene)
    for kind, extra, unit in (("dataset", DATASET, "frames"), ("study", STUDY, "candidates")):
        runs = {1: [], 2: []}
        for i in range(repeat):
            for workers in (1, 2):
                out = workdir / f"{kind}_w{workers}_{i}"
                shutil.rmtree(out, ignore_errors=True)
                run = run_cli([kind, scene, *extra, "--out", out, "--workers", workers],
                              quiet_wait)
                log(f"bench: scale-out {kind} --workers {workers} ({i + 1}/{repeat}): "
                    f"{run['wall_s']:.1f} s; load {run['load_before']:.2f}, other work "
                    f"{run['others_before']} cores before, {run['others_during']} during")
                runs[workers].append(run)
        best = {w: min(runs[w], key=lambda r: r["wall_s"]) for w in (1, 2)}
        s1 = best[1]["summary"]
        if kind == "study":  # the timings are in the report
            s1["timing_s"] = json.loads(
                (workdir / f"{kind}_w1_{runs[1].index(best[1])}" / "study.json").read_text()
            )["timing_s"]
        count = len(s1["frames"]) if kind == "dataset" else s1["candidates"]
        got = {}
        for w in (1, 2):
            got[str(w)] = {"wall_s": best[w]["wall_s"], "rate": count / best[w]["wall_s"],
                           "runs": [{k: r[k] for k in ("wall_s", "load_before",
                                                       "others_before", "others_during",
                                                       "own_cpu_s")} for r in runs[w]],
                           "best": runs[w].index(best[w])}
        same = [compare(workdir / f"{kind}_w1_0", workdir / f"{kind}_w2_{i}", kind)
                for i in range(repeat)]
        # Worker start-up alone: the same command with pieces of one scan or candidate.
        out = workdir / f"{kind}_startup"
        shutil.rmtree(out, ignore_errors=True)
        run = run_cli([kind, scene, *PROBES[kind], "--out", out, "--workers", 2], quiet_wait)
        start = startup(run)
        log(f"bench: scale-out {kind} worker start-up: {start:.2f} s; load "
            f"{run['load_before']:.2f}, other work {run['others_during']} cores")
        b = breakdown(best[2], 2, start)
        est, limit = estimate(best[1]["wall_s"], b) if b else (None, None)
        res[kind] = {"unit": unit, "count": count,
                     "scans": s1.get("scanned") if kind == "dataset" else None,
                     "runs": got, "ratio": best[1]["wall_s"] / best[2]["wall_s"],
                     "identical": same, "breakdown": b, "estimate": est, "limit": limit,
                     "serial_timing": s1.get("timing_s")}
        if kind == "dataset":
            res[kind]["serial_work_s"] = s1["seconds"]
            res[kind]["break_even"] = break_even(res[kind])
            summaries = {"dataset": s1}
        else:
            summaries["study"] = s1
        log(f"bench: scale-out {kind}: {got['1']['rate']:.2f} -> {got['2']['rate']:.2f} {unit}/s "
            f"({res[kind]['ratio']:.2f}x), outputs identical: "
            f"{all(x['identical'] for x in same)}")
    traffic = STUDY[STUDY.index("--traffic") + 1]
    lo, hi, step = (int(v) for v in traffic.replace(":", "-").split("-"))
    res["cost_model"] = cost_model(summaries["dataset"], summaries["study"],
                                   len(range(lo, hi + 1, step)))
    res["load_end"] = load()
    res["seconds"] = time.perf_counter() - t_start
    if own:
        shutil.rmtree(workdir, ignore_errors=True)
    return res


# ---- the report -------------------------------------------------------------------------

def _cell(r, unit):
    runs = "; ".join(f"{x['wall_s']:.1f} s at {x['load_before']:.2f} / {x['others_during']:.2f}"
                     for x in r["runs"])
    return f"{r['wall_s']:.1f} s, **{r['rate']:.2f} {unit}/s** (runs: {runs})"


def section(res):
    """The "Scale-out" section of docs/benchmarks.md (markdown lines)."""
    d, s = res["dataset"], res["study"]
    L = ["## Scale-out (Dask)\n"]
    L.append(f"`bench/scale_out.py`, {res['date']}, {res['cores']} cores, {res['seconds']:.0f} s "
             f"for this section (load average {res['load_start']:.2f} at its start, "
             f"{res['load_end']:.2f} at its end). Scene: {res['scene']}. Each command runs "
             "as a user runs it (`python -m rls_addon ...` in a subprocess); wall times from "
             f"launch to exit, best of {res['repeat']}, runs with 1 and 2 workers "
             "alternating. In brackets, for each run: its wall time at the load average "
             "before it / the cores other work kept busy during it (the machine's busy CPU time less the "
             "command's own; above ~0.2 the two workers shared the cores with something "
             "else). `--workers 1` runs in the command's own process (Embree on every "
             "core); `--workers 2` starts a Dask LocalCluster of two worker processes (one "
             "Embree thread each).\n")
    L.append("| run | `--workers 1` | `--workers 2` | ratio (target >= 1.7x) | 2-worker "
             "outputs = 1-worker outputs |")
    L.append("|---|---|---|---|---|")
    whats = {"dataset": f"`rls dataset {' '.join(DATASET)}`: {d['scans']} scans, "
                        f"{d['count']} frames",
             "study": f"`rls study {' '.join(STUDY)}`: {s['count']} candidates"}
    for name, r in (("dataset", d), ("study", s)):
        what = whats[name]
        cells = [_cell(r["runs"][w], r["unit"]) for w in ("1", "2")]
        same = r["identical"]
        if all(x["identical"] for x in same):
            verdict = ("yes, byte for byte" if name == "dataset" else
                       "yes, the same tables, report and charts (timing columns aside)")
        else:
            verdict = "**no** (" + ", ".join(sorted({f for x in same for f in x["differ"]})) + ")"
        met = "**met**" if r["ratio"] >= TARGET else "**missed**"
        L.append(f"| {what} | {cells[0]} | {cells[1]} | {r['ratio']:.2f}x {met} | "
                 f"{verdict}: sha256 of {same[0]['files']} files, every 2-worker run |")
    L.append("")
    L.append("Where the time of the best 2-worker run goes (s since launch, from its stderr "
             "lines as they arrive). *Pieces handed out*: the command's start-up, the scene "
             "(the study also prepares its scanner) and the cluster up. *Worker start-up*: "
             "the workers import bpy, open the scene (the study's prepare their scanner); "
             "measured apart, as pieces handed out to first piece back in the same command "
             "with pieces of one scan (`--frames 1`) or one candidate (`--k 1 --mount 'TL "
             "NE' --pitch 0`), one run. *Parallel part*: 2 x (last piece "
             "back - pieces handed out - worker start-up), a worker waiting for the other's "
             "last piece counted as busy; *per shard* = parallel part / pieces. *Tail*: "
             "after the last piece (the dataset's split files; the study's search, charts "
             "and report), in the command's process. *Serial part* = pieces handed out + "
             "tail.\n")
    L.append("| run | pieces | pieces handed out | worker start-up | first piece back | "
             "last piece back | tail | wall | serial part | parallel part | per shard |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, r in (("dataset", d), ("study", s)):
        b = r["breakdown"]
        if not b:
            L.append(f"| {name} | n/a |" + " |" * 9)
            continue
        L.append(f"| {name} | {b['pieces']} | {b['handed_out_s']:.1f} | "
                 f"{b['worker_startup_s']:.1f} | {b['first_piece_s']:.1f} | "
                 f"{b['last_piece_s']:.1f} | {b['tail_s']:.1f} | {b['wall_s']:.1f} | "
                 f"{b['serial_s']:.1f} | {b['parallel_s']:.1f} | {b['shard_s']:.2f} |")
    L.append("")
    L.append("**Estimate** for N workers on N cores as fast as these (Amdahl: T(N) = serial "
             "part + worker start-up + parallel part / N, the three as the 2-worker run "
             "measured them, so N = 2 gives its wall time; N = 1 is the measured in-process "
             "run; *limit*: the speed-up as N grows). An estimate, not a measurement: it "
             "assumes the workers start in parallel, the work does not grow with N and the "
             "pieces (4 per worker) stay as balanced.\n")
    ns = [e["workers"] for e in (d["estimate"] or s["estimate"] or [])]
    L.append("| run | serial + start-up (s) | parallel (s) | " + " | ".join(
        f"N = {n}" for n in ns) + " | limit |")
    L.append("|---" * (len(ns) + 4) + "|")
    for name, r in (("dataset", d), ("study", s)):
        b, est = r["breakdown"], r["estimate"]
        if not est:
            continue
        L.append(f"| {name} | {b['serial_s'] + b['worker_startup_s']:.1f} | "
                 f"{b['parallel_s']:.1f} | " + " | ".join(
                     f"{e['seconds']:.1f} s ({e['speedup']:.2f}x)" for e in est)
                 + f" | {r['limit']:.1f}x |")
    L.append("")
    cm, be = res.get("cost_model"), d.get("break_even")
    if cm:
        c, md, ms_ = cm["constants"], cm["dataset"], cm["study"]
        L.append(f"**`--workers auto`** (`rls_addon/core/scan/dask_run.py`) estimates a run's time "
                 f"in one process as scans x {c['SECONDS_PER_SCAN']:g} s + rays x "
                 f"{c['SECONDS_PER_RAY']:g} s and starts workers above "
                 f"{c['AUTO_MIN_SECONDS']:g} s. Measured in the 1-worker runs above: the "
                 f"dataset's {md['scans']} scans ({md['rays'] / 1e6:.1f} M rays) took "
                 f"{md['run_s']:.1f} s in the run ({md['scan_s']:.1f} s scanning: "
                 f"{md['per_ray_s'] * 1e9:.0f} ns per ray; {md['per_scan_s'] * 1000:.0f} ms "
                 f"per scan for the rest: frame changes, ground truth, files), the model says "
                 f"{md['model_s']:.1f} s; the study's {ms_['scans']} scans "
                 f"({ms_['rays'] / 1e6:.1f} M rays) took {ms_['run_s']:.1f} s "
                 f"({ms_['per_scan_s'] * 1000:.0f} ms per scan), the model says "
                 f"{ms_['model_s']:.1f} s.")
        if be:
            far = ("never reached" if be["x1_7_s"] == float("inf")
                   else f"from about {be['x1_7_s']:.0f} s")
            L.append(f"From the dataset's fit (one process: {be['serial_fixed_s']:.1f} s "
                     f"besides the run's work P; two workers: "
                     f"{be['two_worker_fixed_s']:.1f} s of serial part and start-up, and "
                     f"between them {be['work_ratio']:.2f} x P of work), two workers beat one "
                     f"process above about {be['break_even_s']:.0f} s of work, are 1.3x "
                     f"faster above about {be['x1_3_s']:.0f} s, 1.7x {far}, and at most "
                     f"{be['bound']:.2f}x.")
        L.append("")
    return L


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "build" / "bench"),
                    help="folder for scale_out.json and scale_out.md (default build/bench)")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each command (best of)")
    ap.add_argument("--workdir", default=None,
                    help="keep the scene and the outputs here (default: a temporary folder)")
    ap.add_argument("--quiet-wait", type=float, default=0.0, metavar="S",
                    help="wait up to S seconds before each run for other work to stop")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res = measure(args.workdir, args.repeat, args.quiet_wait)
    (out / "scale_out.json").write_text(json.dumps(res, indent=1))
    (out / "scale_out.md").write_text("\n".join(section(res)))
    print(json.dumps({k: {"ratio": round(res[k]["ratio"], 2),
                          "identical": all(x["identical"] for x in res[k]["identical"]),
                          "rates": {w: round(res[k]["runs"][w]["rate"], 3) for w in ("1", "2")}}
                      for k in ("dataset", "study")} | {"seconds": round(res["seconds"])}))


if __name__ == "__main__":
    main()
