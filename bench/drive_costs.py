"""Moving sensors at the cost of their casts (issue 40): a LiDAR driving through the
sample intersection's traffic written as a dataset, and one driving over the open sky,
each frame against the cast of its rays.

* traffic: a Hesai Pandar64 on a car driving at 10 m/s along the eastbound lane of the
  sample intersection (``rls_addon/blender/scenes``: its vehicles, pedestrians and
  cyclists keyed at every frame), written with ``rls dataset --layout kitti`` (clouds,
  ground-truth boxes, labels) and with ``rls scan`` (clouds and sidecars, boxes in
  them);
* open sky: the Pandar64 driving at 10 m/s over ``scene.open_sky_geometry`` with
  ``rls scan`` (``frame_costs.BUILD_DRIVE``);
* parked cars: the traffic drive again, written as a dataset, with 72 parked cars
  added in rows along the sidewalks (``BUILD_PARKED``): a street's many objects that
  stand still, each with a ground-truth box. No target: it shows what a frame pays
  per object that does not move (reading it, its box).

Each command runs as a user runs it (``python -m rls_addon`` in a subprocess). Wall time
per frame = (a run of N frames - a run of its first frame) / (N - 1), each run timed by
its own clock: the ``seconds`` of the JSON summary it prints (from the run's start, once
Python, Blender and the file are loaded, to its end, its last files written). The
whole processes' difference is reported beside it: the same frames' cost, plus the
start-up's spread between two processes (Blender loading, 1.0-1.3 s on this machine),
which over 40 frames moves a frame's figure by several milliseconds. The runs of the
commands and the casts below take turns, ``repeat`` rounds, and the medians are reported
(the machine is shared: a burst of load falls on all of them alike).

The cast: Open3D's ``RaycastingScene`` (Embree 3 on every core) casting the pattern's
rays from the sensor's pose at the middle frame into every triangle of the scene at
that frame (the traffic where it stands then), median of 20 casts, in a subprocess of
its own, once per round.

The breakdown: the same frames run in one process through the command's own
``ScanRun`` (``commands.dataset.dataset_run``, ``commands.scan.scan_run``), each stage
timed where the core calls it (``STAGES``); medians per frame. Then the same frames
twice more in that process: once keeping the result of every cast the run makes
(``World.start``), once with each cast given back at once from what was kept (the files
both write compared, byte for byte): the CPU a frame costs besides its casts. Last, our
own cast of the middle frame (its rays each at its own firing time, into that sweep's
static scene and moving instances) repeated alone, median of 25, reported beside
Open3D's. Neither part holds the moving instances' set-up that ``World.start`` makes
once a sweep (their motion steps and Embree scene, about 2.5 ms of CPU a traffic frame
measured alone): the replay never calls it, and the repeated cast finds it made.

Targets: the traffic drive with boxes <= 3x its cast, the open-sky drive <= 2x.

    .venv/bin/python -m bench.drive_costs [--quick]     (prints JSON, then markdown)
"""

import json
import os
import resource
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

REPEAT = 5  # rounds taking turns (3 left the medians 20-40% apart between runs)
TARGETS = {"traffic_dataset": 3.0, "traffic_scan": 3.0, "sky_scan": 2.0}
SPEED_MPS = 10.0

BUILD_TRAFFIC = r"""
import sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.read_factory_settings(use_empty=True)
rls_addon.ensure_registered()
from rls_addon.blender.scenes import build_scene
scene = bpy.context.scene
build_scene("intersection", scene)
lidar = bpy.data.objects.new("LiDAR", None)
scene.collection.objects.link(lidar)
s = lidar.rls_lidar
s.is_lidar, s.preset_id = True, "hesai_pandar64"
speed = float(sys.argv[3])
for frame, x in ((1, -50.0), (101, -50.0 + speed * 10.0)):  # 10 frames per second
    lidar.location = (x, -1.75, 1.9)  # the eastbound inner lane, on a car's roof
    lidar.keyframe_insert("location", frame=frame)
from bpy_extras import anim_utils
ad = lidar.animation_data
for fc in anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot).fcurves:
    for kp in fc.keyframe_points:
        kp.interpolation = "LINEAR"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""

BUILD_PARKED = r"""
import sys, bpy, bmesh
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
rls_addon.ensure_registered()
scene = bpy.context.scene
mesh = bpy.data.meshes.new("Parked car")
bm = bmesh.new()
bmesh.ops.create_cube(bm, size=1.0)
bm.to_mesh(mesh)
bm.free()
cars = bpy.data.collections.new("Parked")
scene.collection.children.link(cars)
# nine cars 5 m apart on each of the eight sidewalk stretches (the sample intersection:
# roads |y| <= 7 and |x| <= 7, sidewalks 4 m wide, raised 0.15 m), clear of the junction
n = 0
for side in (1, -1):
    for start in (14.0, -58.0):
        for k in range(9):
            along = start + 2.25 + 5.0 * k
            for x, y, yaw in ((along, side * 9.0, 0.0), (side * 9.0, along, 1.5707963)):
                car = bpy.data.objects.new(f"Parked car {n:03d}", mesh)
                car.location = (x, y, 0.9)
                car.rotation_euler = (0.0, 0.0, yaw)
                car.scale = (4.5, 1.8, 1.5)
                car["rls_label"] = "vehicle"
                cars.objects.link(car)
                n += 1
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
"""

# Where the core spends a frame: (module, attribute, stage). The stages nest: the
# session's scan holds the sweep, the bodies and the frame; the boxes are worked out on
# the writer's thread, behind the scan (``io.behind.Later``), overlapping the next frame:
# their wall time there is not part of the step.
STAGES = [
    ("rls_addon.blender.source", "BlenderScene.set_frame", "Blender: frame change"),
    ("rls_addon.blender.source", "BlenderScene.read", "Blender: scene read"),
    ("rls_addon.core.scan.session", "classify", "sweep sampled and classified"),
    ("rls_addon.core.scan.session", "ScanSession._bodies_of", "moving bodies"),
    ("rls_addon.core.scan.session", "scan_frame_started", "scan_frame: rays aimed, cast started"),
    ("rls_addon.core.scan.session", "finished", "scan_frame: cast collected, points made"),
    ("rls_addon.core.scan.session", "object_boxes", "ground-truth boxes (writer's thread)"),
    ("rls_addon.core.scan.session", "sensor_pose_record", "sidecar: sensor poses"),
]

BREAKDOWN = r"""
import importlib, json, statistics, sys, tempfile, time
root, command, blend, frames, out = sys.argv[1:6]
sys.path.insert(0, root)
import bpy
import rls_addon
from rls_addon.cli import build_parser
stages = json.loads(sys.argv[6])
spent = {}

def timed(owner, name, label):
    attr = owner.__dict__.get(name) if isinstance(owner, type) else None
    fn = getattr(owner, name, None)
    if fn is None:
        return False
    def wrapper(*a, **k):
        t = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            spent[label] = spent.get(label, 0.0) + time.perf_counter() - t
    setattr(owner, name, staticmethod(wrapper) if isinstance(attr, staticmethod) else wrapper)
    return True

found = []
for module, path, label in stages:
    owner = importlib.import_module(module)
    *outer, name = path.split(".")
    for part in outer:
        owner = getattr(owner, part)
    if timed(owner, name, label):
        found.append(label)
argv = [command, blend, "--frames", frames, "--out", out, "--workers", "1", "--overwrite"]
if command == "dataset":
    argv += ["--layout", "kitti"]

def start_run():
    args = build_parser().parse_args(argv)
    args.prepare_blender = rls_addon.ensure_registered
    if command == "dataset":
        from rls_addon.commands.dataset import dataset_run
        run, writer, _ = dataset_run(args)  # (the background sweeps: none for a moving LiDAR)
        return run, writer
    from rls_addon.commands.scan import scan_run
    run = scan_run(args)
    return run, run.writer

run, writer = start_run()
write = writer.write
def timed_write(*a, **k):
    t = time.perf_counter()
    try:
        return write(*a, **k)
    finally:
        spent[WRITE] = spent.get(WRITE, 0.0) + time.perf_counter() - t
WRITE = "files written (or handed to the writer's thread)"
writer.write = timed_write
rows = []
run.step()  # the first frame builds what the run keeps
cpu0, main0 = time.process_time(), time.thread_time()
while True:
    spent.clear()
    t = time.perf_counter()
    more = run.step()
    row = dict(spent, frame=time.perf_counter() - t)
    rows.append(row)
    if not more:
        break
t = time.perf_counter()
run.finish()
# CPU of the steps by thread (the last step's files written by finish included)
cpu, main = time.process_time() - cpu0, time.thread_time() - main0
finish_s = time.perf_counter() - t

# The same frames again, twice: once keeping every cast's result (World.start, in the
# order the run asks for them), then once with each cast given back at once from what
# was kept: the CPU of everything a frame does but its casts.
from rls_addon.core.world import world as world_module
import numpy as np
# A driving sensor's step starts its cast before it collects the previous frame's, so
# each result is kept in the slot of its start. The files written both times are
# compared: the run without casts must write what the run with them wrote.
import hashlib, pathlib
cast_start, kept = world_module.World.start, []
sizes = []  # the rays of every cast, in the order of their starts
def keeping(self, *a, **k):
    finish = cast_start(self, *a, **k)
    sizes.append(len(a[1]))
    slot = len(kept)
    kept.append(None)
    def kept_finish():
        got = finish()
        kept[slot] = tuple(np.copy(x) for x in got)
        return got
    return kept_finish
def replaying(self, *a, **k):
    got = kept.pop(0)  # each kept result is given once: the run may change it
    return lambda: got
def written():
    return {str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(pathlib.Path(out).rglob("*")) if p.is_file()}
cpu_rest, files = None, []
for hook in (keeping, replaying):
    world_module.World.start = hook
    run, _ = start_run()
    run.step()
    cpu0, steps = time.process_time(), 0
    while True:
        steps += 1
        if not run.step():
            break
    run.finish()
    cpu_rest = (time.process_time() - cpu0) / steps
    files.append(written())
world_module.World.start = cast_start
same = files[0] == files[1]
# Our own cast of the middle frame alone (the frame's rays, each at its own time, into
# that sweep's world: the static scene and the moving instances), median of 25: what
# the frame's cast costs here, beside Open3D's cast of the scene frozen at that frame.
# The frames' casts are those with the most rays (the others are ghosts' bounces); a
# fourth run takes the middle one's world and rays as it starts it.
frames_cast = [j for j, n in enumerate(sizes) if n == max(sizes)]
chosen, call, count = frames_cast[len(frames_cast) // 2], [], [0]
def capturing(self, *a, **k):
    if count[0] == chosen:
        call.append((self, a, dict(k, reuse=False)))
    count[0] += 1
    return cast_start(self, *a, **k)
world_module.World.start = capturing
run, _ = start_run()
while run.step():
    pass
run.finish()
world_module.World.start = cast_start
w, a, k = call[0]
walls, cpus = [], []
for _ in range(25):
    t, c = time.perf_counter(), time.process_time()
    cast_start(w, *a, **k)()
    walls.append(time.perf_counter() - t)
    cpus.append(time.process_time() - c)
print(json.dumps({"rows": rows, "finish_s": finish_s,
                  "own_cast_s": statistics.median(walls),
                  "own_cast_cpu_s": statistics.median(cpus),
                  "stages": found + [WRITE],
                  "cpu_s": {"scan's thread": main / len(rows),
                            "other threads": (cpu - main) / len(rows)},
                  "cpu_without_casts_s": cpu_rest, "casts_left": len(kept),
                  "replay_same": same}))
"""

CAST = r"""
import json, statistics, sys, time
sys.path.insert(0, sys.argv[1])
import bpy, numpy as np
import rls_addon
rls_addon.ensure_registered()
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
import open3d as o3d
from rls_addon.blender.source import BlenderScene
from rls_addon.blender.sensor import lidar_objects, sensor_job
from rls_addon.core.scan.frame import sensor_axes
from rls_addon.core.scan.settings import scan_pattern
from rls_addon.core.scene.instances import object_table, world_geometry
scene = bpy.context.scene
frame = int(sys.argv[3])
source = BlenderScene(scene, edited=False)
source.set_frame(frame)
lidar = lidar_objects(scene)[0]
job = sensor_job(lidar)
pose = source.sensor_pose(lidar.name)
read = source.read(pose[:3, 3], 1e9, {lidar.name})
geometry = world_geometry(read.instances, object_table(read.instances), read.materials)
pattern = scan_pattern(job.preset, job.settings.scan, frame)
origin, rot = sensor_axes(pose)
dirs = pattern.rotated(rot)
rays = np.concatenate([np.broadcast_to(origin, dirs.shape), dirs], 1).astype(np.float32)
rs = o3d.t.geometry.RaycastingScene()
rs.add_triangles(o3d.core.Tensor(geometry.vertices.astype(np.float32)),
                 o3d.core.Tensor(geometry.triangles.astype(np.uint32)))
rays = o3d.core.Tensor(rays)
rs.cast_rays(rays)
times = []
for _ in range(20):
    t = time.perf_counter()
    rs.cast_rays(rays)
    times.append(time.perf_counter() - t)
print(json.dumps({"cast_s": statistics.median(times), "rays": len(dirs),
                  "triangles": int(geometry.triangle_count)}))
"""


def _python(script, *args, timeout=3600):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", script, str(ROOT), *map(str, args)],
                          env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"bench drive_costs: {proc.stderr[-2000:]}")
    return proc.stdout


def _rls(*args, timeout=3600):
    """(wall seconds, CPU seconds of all its threads, the run's own seconds: its JSON
    summary's) of ``python -m rls_addon ...`` as a user runs it."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "rls_addon", *map(str, args)], env=env,
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"rls {args[0]} failed: {proc.stderr[-2000:]}")
    own = float(json.loads(proc.stdout)["seconds"])
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime), own


CASES = {  # name: (scene file, command, frames)
    "traffic_dataset": ("traffic.blend", "dataset", (2, 60)),
    "traffic_scan": ("traffic.blend", "scan", (2, 60)),
    "sky_scan": ("sky.blend", "scan", (1, 41)),
    "parked_dataset": ("parked.blend", "dataset", (2, 60)),
}


def _command(name, blend, frames, out):
    _, command, _ = CASES[name]
    args = [command, blend, "--frames", frames, "--out", out, "--workers", "1",
            "--overwrite"]
    return args + (["--layout", "kitti"] if command == "dataset" else [])


def measure(quick=False, repeat=None):
    from bench.frame_costs import BUILD_DRIVE

    repeat = repeat or (1 if quick else REPEAT)
    cases = {k: (b, c, (f0, f0 + 20) if quick else (f0, f1))
             for k, (b, c, (f0, f1)) in CASES.items()}
    out = {"cases": {}, "repeat": repeat, "loadavg_start": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="rls-drive-") as tmp:
        tmp = Path(tmp)
        _python(BUILD_TRAFFIC, tmp / "traffic.blend", SPEED_MPS)
        _python(BUILD_DRIVE, tmp / "sky.blend")
        _python(BUILD_PARKED, tmp / "traffic.blend", tmp / "parked.blend")
        walls = {k: [] for k in cases}
        owns = {k: [] for k in cases}
        cpus = {k: [] for k in cases}
        casts = {k: [] for k in cases}
        for _ in range(repeat):  # taking turns
            for name, (blend, _, (f0, f1)) in cases.items():
                one = _rls(*_command(name, tmp / blend, f"{f0}-{f0}", tmp / name))
                many = _rls(*_command(name, tmp / blend, f"{f0}-{f1}", tmp / name))
                walls[name].append((many[0] - one[0]) / (f1 - f0))
                owns[name].append((many[2] - one[2]) / (f1 - f0))
                cpus[name].append((many[1] - one[1]) / (f1 - f0))
                casts[name].append(json.loads(
                    _python(CAST, tmp / blend, (f0 + f1) // 2).strip().splitlines()[-1]))
        for name, (blend, command, (f0, f1)) in cases.items():
            got = json.loads(_python(BREAKDOWN, command, tmp / blend, f"{f0}-{f1}",
                                     tmp / f"{name}-stages",
                                     json.dumps(STAGES)).strip().splitlines()[-1])
            rows = got["rows"]
            if got["casts_left"] or not got["replay_same"]:
                raise RuntimeError(f"bench drive_costs: {name}'s run with its casts given "
                                   "back did not write what the run with them wrote")
            stages = {label: statistics.median(r.get(label, 0.0) for r in rows)
                      for label in got["stages"]}
            wall = statistics.median(owns[name])
            cast = statistics.median(c["cast_s"] for c in casts[name])
            out["cases"][name] = {
                "command": command, "frames": [f0, f1], "own_s": owns[name],
                "per_frame_s": wall, "wall_s": walls[name],
                "process_per_frame_s": statistics.median(walls[name]), "cpu_s": cpus[name],
                "cpu_per_frame_s": statistics.median(cpus[name]), "cast_s": cast,
                "casts_s": [c["cast_s"] for c in casts[name]], "rays": casts[name][0]["rays"],
                "triangles": casts[name][0]["triangles"], "ratio": wall / cast,
                "stage_s": stages, "thread_cpu_s": got["cpu_s"],
                "cpu_without_casts_s": got["cpu_without_casts_s"],
                "own_cast_s": got["own_cast_s"], "own_cast_cpu_s": got["own_cast_cpu_s"],
                "step_s": statistics.median(r["frame"] for r in rows)}
    out["loadavg_end"] = os.getloadavg()[0]
    return out


def section(r):
    names = {"traffic_dataset": "through the sample intersection's traffic, "
                                "`rls dataset --layout kitti`",
             "traffic_scan": "the same drive, `rls scan`",
             "sky_scan": "over the open sky, `rls scan`",
             "parked_dataset": "through the traffic with 72 parked cars, `rls dataset "
                               "--layout kitti`"}

    def ms(s):
        return f"{s * 1e3:.1f} ms"

    lines = [
        "## Moving sensors against their casts (issue 40)\n",
        "`bench/drive_costs.py`: a Hesai Pandar64 driving at 10 m/s, each command run as a "
        "user runs it (`python -m rls_addon`, one process, `--workers 1`). *Per frame*: "
        "(wall time of frames A-B - wall time of frame A alone) / (B - A), each run "
        "timed by its own clock (the `seconds` of the JSON summary it prints: from the "
        "run's start, Python, Blender and the file loaded, to its end, its last files "
        "written). *Whole process*: the same difference of the two processes' wall "
        "times, which adds the spread of Blender's start-up between them (1.0-1.3 s "
        "here, several milliseconds a frame over 40 frames). *Cast*: "
        "Open3D's `RaycastingScene` (Embree 3 on every core) casting the pattern's rays "
        "from the sensor's pose at the middle frame into every triangle of the scene at "
        "that frame, median of 20 casts. The commands and the casts take turns, "
        f"{r['repeat']} rounds; the medians are shown. *CPU per frame*: the same "
        "difference of the two runs' CPU time (every thread of the process: the casts', "
        "the file writer's), less sensitive than wall time to other work on the machine. "
        "Targets: the traffic drive with boxes <= 3x its cast, the open-sky drive <= 2x; "
        "the drive past parked cars has none (what a frame pays per object that stands "
        "still). *Our cast alone*: the cast a frame makes here (the middle frame's rays, "
        "each at its own firing time, into that sweep's world: the static scene and the "
        "moving instances, with the watertight re-check), repeated alone in the breakdown's "
        "process, median of 25, its world's moving instances already set up (their "
        "motion steps and Embree scene, made once a sweep: about 2.5 ms of CPU a traffic "
        "frame measured alone); the targets are against Open3D's cast, this column is "
        "beside it.\n",
        "| drive | frames | rays / triangles | cast | per frame | per frame / cast | target "
        "| whole process per frame | CPU per frame | our cast alone | per frame / our cast |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, c in r["cases"].items():
        target = TARGETS.get(name)
        ok = "-" if target is None else \
            f"<= {target:g}x " + ("**met**" if c["ratio"] <= target else "**not met**")
        lines.append(
            f"| {names[name]} | {c['frames'][0]}-{c['frames'][1]} | {c['rays']:,} / "
            f"{c['triangles']:,} | {ms(c['cast_s'])} (casts: "
            f"{', '.join(f'{w * 1e3:.1f}' for w in c['casts_s'])} ms) | {ms(c['per_frame_s'])} "
            f"(runs: {', '.join(f'{w * 1e3:.1f}' for w in c['own_s'])} ms) | "
            f"**{c['ratio']:.1f}x** | {ok} | {ms(c['process_per_frame_s'])} "
            f"({c['process_per_frame_s'] / c['cast_s']:.1f}x; runs: "
            f"{', '.join(f'{w * 1e3:.0f}' for w in c['wall_s'])} ms) | "
            f"{ms(c['cpu_per_frame_s']) if 'cpu_per_frame_s' in c else '-'} | "
            + (f"{ms(c['own_cast_s'])} ({ms(c['own_cast_cpu_s'])} of CPU) | "
               f"{c['per_frame_s'] / c['own_cast_s']:.1f}x |" if "own_cast_s" in c
               else "- | - |"))
    labels = []
    for c in r["cases"].values():
        labels += [k for k in c["stage_s"] if k not in labels]
    lines += ["",
              "Where a frame goes: the same frames in one process through the command's own "
              "`ScanRun`, each stage timed where the core calls it (medians per frame; the "
              "session's scan holds the sweep, the bodies and `scan_frame`; a driving "
              "sensor's step starts its frame's cast and then ends the previous frame "
              "(its cast collected, its points made, its files handed to the writer) "
              "while that cast runs; the boxes are worked out on the writer's thread "
              "behind the scan, overlapping the next frame, so their wall time there "
              "(stretched by waiting for Python's lock) is not part of the step; "
              "*step* is the whole step of the run, what the stages leave of it is the "
              "session's and the run's own work).\n",
              "| stage | " + " | ".join(names[n].split(",")[0] if n != "traffic_scan"
                                        else "traffic, `rls scan`"
                                        for n in r["cases"]) + " |",
              "|---|" + "---|" * len(r["cases"])]
    for label in labels:
        lines.append(f"| {label} | " + " | ".join(
            ms(c["stage_s"][label]) if label in c["stage_s"] else "-"
            for c in r["cases"].values()) + " |")
    lines.append("| *step* | " + " | ".join(ms(c["step_s"]) for c in r["cases"].values())
                 + " |")
    for thread in THREADS:
        lines.append(f"| CPU of a step: {thread} | " + " | ".join(
            ms(c["thread_cpu_s"][thread]) if "thread_cpu_s" in c else "-"
            for c in r["cases"].values()) + " |")
    lines.append("| CPU of a step without its casts (given back at once) | " + " | ".join(
        ms(c["cpu_without_casts_s"]) if "cpu_without_casts_s" in c else "-"
        for c in r["cases"].values()) + " |")
    lines += ["", f"Load average at the start / end: {r['loadavg_start']:.2f} / "
                  f"{r['loadavg_end']:.2f}.", "",
              f"![moving sensors against their casts]({CHART})", "",
              "*CPU of a step by thread*: the scan's thread (Blender, the sweep and the "
              "per-ray work in Python and numpy) and the other threads (the cast's "
              "workers, the compiled stages' second shares and the writer's thread with "
              "the ground-truth boxes and files). *Without its casts*: the same frames run "
              "twice more in the same process, first keeping the result of every cast "
              "the run makes (`World.start`: the frame's rays and its ghosts' bounces), "
              "then with each cast given back at once from those results; the CPU of "
              "that last run per step is what a frame costs besides its casts and the "
              "moving instances' set-up that the casts make.", "",
              "Left: a frame against Open3D's cast (the target's) and against our own cast "
              "of it alone. Right: a frame's CPU as two parts measured apart, everything "
              "but the casts (the run with its casts given back) and our cast of the "
              "middle frame alone, with the whole step's CPU in the breakdown's run (the "
              "tick: the parts plus the threads' waiting on each other and on the "
              "machine), against what the target leaves a frame on this machine's cores "
              "used in full (the target's wall time times the cores).", ""]
    return lines


THREADS = ("scan's thread", "other threads")
CHART = "bench_drive_costs.png"
NAMES = {"traffic_dataset": "traffic, dataset", "traffic_scan": "traffic, scan",
         "sky_scan": "open sky, scan", "parked_dataset": "72 parked cars, dataset"}


def chart(r, path):
    """Two panels: each drive's frame against its cast (and the target), and a frame's
    CPU by thread against the CPU the target leaves on this machine's cores."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = list(r["cases"].items())
    cores = os.cpu_count() or 1
    y = list(range(len(cases)))[::-1]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.4), sharey=True)
    cast = [c["cast_s"] * 1e3 for _, c in cases]
    frame = [c["per_frame_s"] * 1e3 for _, c in cases]
    own = [c.get("own_cast_s", 0.0) * 1e3 for _, c in cases]
    ax[0].barh([v + 0.27 for v in y], frame, 0.27, color="C0", label="a frame (per frame)")
    ax[0].barh(y, cast, 0.27, color="0.6", label="its cast (Open3D, the target's)")
    ax[0].barh([v - 0.27 for v in y], own, 0.27, color="0.35",
               label="our cast of it alone (each ray at its own time)")
    for v, (name, c), f in zip(y, cases, frame):
        ax[0].text(f, v + 0.27, f" {c['ratio']:.1f}x", va="center", fontsize=8)
        if name in TARGETS:
            ax[0].plot([TARGETS[name] * c["cast_s"] * 1e3] * 2, [v - 0.45, v + 0.45], "r--",
                       label="target" if v == y[0] else None)
    ax[0].set_xlim(0, max(frame) * 1.15)  # room for the ratios
    ax[0].set_xlabel("ms a frame")
    ax[0].set_title("A frame against its cast")
    total = [sum(c.get("thread_cpu_s", {}).values()) * 1e3 for _, c in cases]
    rest = [c.get("cpu_without_casts_s", 0.0) * 1e3 for _, c in cases]
    ax[1].barh(y, rest, 0.6, color="C0", label="everything but the casts")
    ax[1].barh(y, [c.get("own_cast_cpu_s", 0.0) * 1e3 for _, c in cases], 0.6, left=rest,
               color="0.35", label="+ our cast of the frame alone")
    ax[1].plot(total, y, "k|", markersize=22, markeredgewidth=2,
               label="the whole step, in the run")
    for v, (name, c) in zip(y, cases):
        if name in TARGETS:
            budget = TARGETS[name] * c["cast_s"] * 1e3 * cores
            ax[1].plot([budget] * 2, [v - 0.45, v + 0.45], "r--",
                       label=f"the target's wall time x {cores} cores" if v == y[0] else None)
    ax[1].set_xlabel("ms of CPU a frame")
    ax[1].set_title("A frame's CPU: the rest and our cast")
    for a in ax:  # under the panels: the bars of the longest drive reach the right
        a.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8,
                 frameon=False)
    ax[0].set_yticks(y, [NAMES.get(n, n) for n, _ in cases])
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None):
    numbers = standalone.main(__doc__, measure, section, argv,
                              quick_help="21 frames of each drive, one round")
    chart(numbers, ROOT / "docs" / CHART)
    return numbers


if __name__ == "__main__":
    main()
