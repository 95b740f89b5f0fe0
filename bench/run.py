"""RLS benchmarks: ray-casting backends, frame times, scaling, memory, and a
speed-against-accuracy chart. Writes docs/benchmarks.md and docs/bench_*.png.

    .venv/bin/python bench/run.py [--out docs] [--quick]

Every number comes from this one run on this machine. Times are the best of a few
repeats (the machine may be shared); rays/s count every ray cast, hit or miss.
Baselines on the same rays and triangles: the bare ``BVHTree.ray_cast`` Python loop
and Open3D's ``RaycastingScene.cast_rays``.
"""

import argparse
import datetime
import gc
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from bench.baselines import bare_loop  # noqa: E402
from bench.report import chart_scaling, chart_tessellation, write_report  # noqa: E402

DEVICES = [("Pandar64", "hesai_pandar64"), ("Pandar128", "hesai_pandar128"),
           ("Livox Avia", "livox_avia"), ("RoboSense M1", "robosense_m1")]
SCALING_TRIANGLES = [10_000, 100_000, 300_000, 1_000_000, 2_000_000, 4_000_000]
SCALING_RAYS = [10_000, 30_000, 100_000, 300_000, 1_000_000]
TARGETS = {"embree_vs_open3d": 0.7, "bvh_pipeline_vs_bare": 1.25, "pandar64_realtime": 4.0}


def log(*a):
    print(*a, file=sys.stderr, flush=True)


# ---- machine --------------------------------------------------------------------------

def machine_info():
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = None
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) / 1024 ** 2
    except OSError:
        pass
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    versions = {"python": platform.python_version(), "numpy": np.__version__}
    from importlib.metadata import PackageNotFoundError, version

    for pkg in ("bpy", "embreex", "open3d", "matplotlib"):
        try:
            versions[pkg] = version(pkg)
        except PackageNotFoundError:
            versions[pkg] = "missing"
    return {"cpu": cpu, "cores": cores, "memory_gib": mem, "os": platform.platform(),
            "loadavg_start": os.getloadavg()[0],
            "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"), "versions": versions}


def best(fn, repeat=3):
    """(best wall time in s, last result)."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def preset_or_fallback(label, pid):
    from rls_addon.core.device.presets import get_preset

    try:
        return get_preset(pid), None
    except Exception as exc:  # another preset may be missing in this checkout
        msg = f"preset {pid!r} for {label} is missing ({exc}); using generic_uniform32"
        log("bench: WARNING:", msg)
        return get_preset("generic_uniform32"), msg


def fresh_pattern_time(preset):
    """Seconds to build one frame's pattern from scratch (the preset caches patterns)."""
    preset.__dict__.pop("_pattern_cache", None)
    t = time.perf_counter()
    preset.pattern()
    return time.perf_counter() - t


# ---- backends on the same triangles and rays -------------------------------------------

class Backends:
    """Every backend built once on the same sensor-centred triangles."""

    def __init__(self, geometry, origin, reach, which=("embree", "bvhtree", "open3d"),
                 prepared=True):
        import bpy  # noqa: F401  (mathutils)

        from rls_addon.core.casting import BVHCaster
        from rls_addon.core.casting.embree import EmbreeCaster
        from rls_addon.core.world.bodies import PreparedScene
        from rls_addon.core.scene.geometry import clean_for_casting

        self.origin = np.asarray(origin, float)
        self.build = {}
        self.prepared = {}
        if not prepared:
            which_prepared = ()
        else:
            which_prepared = which
        if "embree" in which_prepared:
            t = time.perf_counter()
            self.prepared["embree"] = PreparedScene(geometry, origin, reach, EmbreeCaster)
            self.build["embree (scene, incl. watertight hull)"] = time.perf_counter() - t
        if "bvhtree" in which_prepared:
            t = time.perf_counter()
            self.prepared["bvhtree"] = PreparedScene(geometry, origin, reach, BVHCaster)
            self.build["bvhtree (scene, incl. watertight hull)"] = time.perf_counter() - t
        if self.prepared:
            ref = next(iter(self.prepared.values()))
            self.vertices, self.triangles = ref.vertices, ref.triangles
        else:
            self.vertices, self.triangles, _, _ = clean_for_casting(geometry, origin, reach)
        self.casters = {}
        if "embree" in which:
            t = time.perf_counter()
            self.casters["embree"] = EmbreeCaster(self.vertices, self.triangles)
            self.build["embree"] = time.perf_counter() - t
            self.casters["embree_1t"] = EmbreeCaster(self.vertices, self.triangles, threads=1)
        if "bvhtree" in which:
            t = time.perf_counter()
            self.casters["bvhtree"] = BVHCaster(self.vertices, self.triangles)
            self.build["bvhtree"] = time.perf_counter() - t
        self.o3d = None
        if "open3d" in which:
            try:
                import open3d as o3d

                t = time.perf_counter()
                sc = o3d.t.geometry.RaycastingScene()
                sc.add_triangles(o3d.core.Tensor(self.vertices.astype(np.float32)),
                                 o3d.core.Tensor(self.triangles.astype(np.uint32)))
                sc.cast_rays(o3d.core.Tensor(np.array([[0, 0, 0, 1, 0, 0]], np.float32)))
                self.build["open3d"] = time.perf_counter() - t
                self.o3d = sc
            except ImportError:
                log("bench: open3d is not installed: no Open3D baseline")

    def cast_times(self, dirs, max_range, repeat=5):
        """Seconds to cast ``dirs`` from the sensor with each backend and baseline: the
        best of ``repeat`` rounds, backends taking turns within a round so that load
        from other work on the machine hits them alike."""
        o = np.zeros((1, 3))
        runs = {}
        for name in ("embree", "embree_1t", "bvhtree"):
            if name in self.casters:
                runs[name] = (lambda c: lambda: c.cast(o, dirs, max_range))(self.casters[name])
        if "bvhtree" in self.casters:
            runs["bare ray_cast loop"] = bare_loop(self.casters["bvhtree"].tree, dirs, max_range)
        if self.o3d is not None:
            import open3d as o3d

            def o3d_cast(threads):
                rays = np.empty((len(dirs), 6), np.float32)
                rays[:, :3] = 0.0
                rays[:, 3:] = dirs
                return self.o3d.cast_rays(o3d.core.Tensor(rays), nthreads=threads)

            runs["open3d"] = lambda: o3d_cast(0)
            runs["open3d_1t"] = lambda: o3d_cast(1)
        slow = {"bvhtree", "bare ray_cast loop"}
        out = {k: float("inf") for k in runs}
        for i in range(repeat):
            for name, fn in runs.items():
                if name in slow and i >= max(2, repeat // 2):
                    continue  # BVHTree runs are long and steadier: fewer repeats
                t = time.perf_counter()
                fn()
                out[name] = min(out[name], time.perf_counter() - t)
        return out


def CountingFactory(factory):
    """A backend wrapping ``factory`` that counts the rays every caster it built was
    asked to cast (primary rays, the watertight re-check of misses, nudged re-casts,
    ghost rays) in its class attribute ``rays``."""
    from rls_addon.core.casting import CasterBase

    class Counted(CasterBase):
        rays = 0

        def __init__(self, vertices, triangles):
            self.inner = factory(vertices, triangles)
            self.name = self.inner.name

        def cast(self, origins, directions, max_dist):
            Counted.rays += len(directions)
            return self.inner.cast(origins, directions, max_dist)
    return Counted


def still_sensor_frame(scene, pattern, pose, preset, settings, repeat):
    """Best time of a frame after the first of a sensor that does not move: the static
    cast kept by ``scene`` is reused (``PreparedScene.cast``); ghosts, noise, dropout
    and points are made anew for every frame (the frame number changes their draws)."""
    from rls_addon.core.scan.frame import scan_frame

    scene.reuse_casts = True
    try:
        scan_frame(scene, pattern, pose, preset, settings, frame=0)  # the first frame casts
        frames = iter(range(1, repeat + 1))
        t, _ = best(lambda: scan_frame(scene, pattern, pose, preset, settings,
                                       frame=next(frames)), repeat)
    finally:
        del scene.reuse_casts
    return t


def rays_cast_per_frame(geometry, pose, preset, factory):
    """Rays actually cast by one default ``scan_frame`` (and by ``PreparedScene.cast``)."""
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    cf = CountingFactory(factory)
    scene = PreparedScene(geometry, pose[:3, 3], preset.range.max_m, cf)
    cf.rays = 0
    scene.cast(pose[:3, 3], preset.pattern().directions @ pose[:3, :3].T, preset.range.max_m)
    prepared = cf.rays
    cf.rays = 0
    scan_frame(scene, preset.pattern(), pose, preset, ScanSettings())
    return {"pattern": len(preset.pattern()), "prepared_cast": prepared, "frame": cf.rays}


# ---- sections --------------------------------------------------------------------------

def devices_section(geometry, pose, quick):
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    origin = pose[:3, 3]
    presets = []
    notes = []
    for label, pid in DEVICES:
        p, note = preset_or_fallback(label, pid)
        presets.append((label, p))
        if note:
            notes.append(note)
    reach = max(p.range.max_m for _, p in presets)
    log(f"bench: building backends on {geometry.triangle_count:,} triangles")
    be = Backends(geometry, origin, reach)
    rows = []
    for label, p in presets:
        pat = p.pattern()
        rays = len(pat)
        dirs = np.ascontiguousarray(pat.directions)
        log(f"bench: {label}: {rays:,} rays per frame")
        rmax = p.range.max_m
        times = be.cast_times(dirs, rmax, repeat=2 if quick else 5)
        settings = ScanSettings()
        bare_settings = _settings(ScanSettings, ghosting=False, noise=False, dropout=False)
        frame, prepared_cast, frame_bare, frame_still = {}, {}, {}, {}
        for name in ("embree", "bvhtree"):
            scene = be.prepared[name]
            k = 7 if name == "embree" else 2
            frame[name], res = best(lambda: scan_frame(scene, pat, pose, p, settings), k)
            prepared_cast[name], _ = best(lambda: scene.cast(origin, dirs, rmax), k)
            frame_bare[name], _ = best(lambda: scan_frame(scene, pat, pose, p, bare_settings), k)
            frame_still[name] = still_sensor_frame(scene, pat, pose, p, settings, k)
        rows.append({"device": label, "preset": p.id, "rays": rays,
                     "frequency_hz": p.frequency_hz, "points": int(len(res.points)),
                     "cast_s": times, "frame_s": frame, "prepared_cast_s": prepared_cast,
                     "frame_no_effects_s": frame_bare, "frame_still_s": frame_still})
    p64 = next((p for label, p in presets if label == "Pandar64"), presets[0][1])
    ghosts = ghosting_cost(be.prepared["embree"], p64.pattern(), pose, p64)
    profile = {name: frame_profile(be.prepared[name], p64.pattern(), pose, p64,
                                   frames=5 if name == "embree" else 2)
               for name in ("embree", "bvhtree")}
    from rls_addon.core.casting.embree import EmbreeCaster

    counts = {label: rays_cast_per_frame(geometry, pose, p, EmbreeCaster) for label, p in presets}
    for row in rows:
        row["rays_cast"] = counts[row["device"]]
    return {"rows": rows, "build_s": be.build, "notes": notes,
            "triangles": int(len(be.triangles)), "ghosting": ghosts, "profile": profile}


def _settings(cls, **want):
    """ScanSettings with those of ``want`` that this engine version has."""
    import dataclasses

    names = {f.name for f in dataclasses.fields(cls)}
    return cls(**{k: v for k, v in want.items() if k in names})


def scaling_triangles(pose, preset, quick):
    from bench.scene import street_geometry

    dirs = np.ascontiguousarray(preset.pattern().directions)
    out = []
    for n in (SCALING_TRIANGLES[:4] if quick else SCALING_TRIANGLES):
        g = street_geometry(n)
        log(f"bench: scaling: {g.triangle_count:,} triangles")
        be = Backends(g, pose[:3, 3], preset.range.max_m, prepared=False)
        t = be.cast_times(dirs, preset.range.max_m, repeat=3)
        out.append({"triangles": g.triangle_count, "build_s": dict(be.build), "cast_s": t})
        del be, g
        gc.collect()
    return out


def scaling_rays(geometry, pose, preset, quick):
    rng = np.random.default_rng(0)
    base = preset.pattern().directions
    be = Backends(geometry, pose[:3, 3], preset.range.max_m, prepared=False)
    out = []
    for n in (SCALING_RAYS[:4] if quick else SCALING_RAYS):
        dirs = np.ascontiguousarray(base[rng.integers(0, len(base), n)])
        log(f"bench: scaling: {n:,} rays")
        out.append({"rays": n, "cast_s": be.cast_times(dirs, preset.range.max_m, repeat=3)})
    return out


MEMORY_CASE = r"""
import json, os, resource, sys, threading, time
sys.path.insert(0, {root!r})
import numpy as np
import bpy
from bench.scene import street_geometry, SENSOR_POSE
from rls_addon.core.scene.geometry import clean_for_casting
from rls_addon.core.device.presets import get_preset
backend, tris = sys.argv[1], int(sys.argv[2])
g = street_geometry(tris)
p = get_preset('hesai_pandar64')
dirs = np.ascontiguousarray(p.pattern().directions)
v, t, _, _ = clean_for_casting(g, SENSOR_POSE[:3, 3], p.range.max_m)
del g
page = os.sysconf('SC_PAGE_SIZE') / 2 ** 20
def rss():
    with open('/proc/self/statm') as f:
        return int(f.read().split()[1]) * page
peak, done = [rss()], [False]
def sample():
    while not done[0]:
        peak[0] = max(peak[0], rss())
        time.sleep(0.002)
before = rss()
th = threading.Thread(target=sample, daemon=True)
th.start()
if backend == 'open3d':
    import open3d as o3d
    sc = o3d.t.geometry.RaycastingScene()
    sc.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(t.astype(np.uint32)))
    rays = np.zeros((len(dirs), 6), np.float32); rays[:, 3:] = dirs
    sc.cast_rays(o3d.core.Tensor(rays))
else:
    if backend == 'embree':
        from rls_addon.core.casting.embree import EmbreeCaster as F
    else:
        from rls_addon.core.casting import BVHCaster as F
    c = F(v, t)
    c.cast(np.zeros((1, 3)), dirs, p.range.max_m)
after = rss()
done[0] = True
th.join()
peak[0] = max(peak[0], after)
print(json.dumps({{'before_mib': before, 'peak_mib': peak[0], 'after_mib': after,
                  'maxrss_mib': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
"""


def memory_section(sizes):
    """Memory of building each backend and casting one Pandar64 frame, one subprocess
    per case: resident memory sampled every 2 ms (peak) and after, against the
    resident memory just before the build (scene arrays already in memory)."""
    out = []
    script = MEMORY_CASE.format(root=str(ROOT))
    for tris in sizes:
        for backend in ("embree", "bvhtree", "open3d"):
            proc = subprocess.run([sys.executable, "-c", script, backend, str(tris)],
                                  capture_output=True, text=True, timeout=600)
            if proc.returncode != 0:
                log(f"bench: memory case {backend} {tris} failed: {proc.stderr[-500:]}")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            out.append({"backend": backend, "triangles": tris, **r,
                        "added_mib": r["peak_mib"] - r["before_mib"]})
            log(f"bench: memory {backend} {tris:,}: +{out[-1]['added_mib']:.0f} MiB")
    return out


# ---- hooks for later work ------------------------------------------------------------

def engine_costs_section(g, pose, preset, quick):
    """The BVHTree frame against the bare loop over exactly the rays it cast; exact
    motion with ten moving cars against snapshot (both backends) and the paper's N
    sub-steps; the InfraNUC estimator's spread against disk count."""
    from bench import engine_costs as ec
    from rls_addon.core.casting import BVHCaster
    from rls_addon.core.casting.embree import EmbreeCaster
    from rls_addon.core.world.bodies import PreparedScene

    log("bench: BVHTree frame against the bare loop over the same rays")
    scene = PreparedScene(g, pose[:3, 3], preset.range.max_m, BVHCaster)
    same = ec.same_rays(scene, preset.pattern(), pose, preset)
    del scene
    gc.collect()
    steps = (1, 4, 16, 64) if quick else (1, 2, 4, 8, 16, 32, 64)
    motion = {}
    for name, factory in (("embree", EmbreeCaster), ("bvhtree", BVHCaster)):
        log(f"bench: ten moving cars, exact vs snapshot vs N sub-steps ({name})")
        motion[name] = ec.motion(g, pose, preset, factory,
                                 substeps=steps if name == "embree" else (), repeat=2)
        gc.collect()
    log("bench: InfraNUC spread against disk count")
    disks = ec.infranuc_disks(seeds=6 if quick else 12)
    return {"same_rays": same, "motion": motion, "disks": disks}


def blender_section(g, pose, device="hesai_pandar64", frames=6):
    """A lidar standing still in Blender over the 1M-triangle street: what a frame costs
    through the add-on's scan session, scene extraction included."""
    import bpy

    import rls_addon
    from bench.scene import add_to_blender
    from rls_addon.blender.extract import read_instances
    from rls_addon.blender.scan import scan_lidar
    from rls_addon.blender.source import BlenderScene
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import EmbreeCaster
    from rls_addon.core.scan.session import MOVER_MARGIN_M, ScanSession

    rls_addon.register()
    try:
        scene = bpy.context.scene
        add_to_blender(g, scene)
        lidar = bpy.data.objects.new("LiDAR", None)
        lidar.matrix_world = [list(r) for r in pose]
        scene.collection.objects.link(lidar)
        lidar.rls_lidar.is_lidar, lidar.rls_lidar.preset = True, device
        session, source = ScanSession(EmbreeCaster), BlenderScene(scene)
        scene.frame_set(1)
        t = time.perf_counter()
        scan_lidar(lidar, 1, session=session, source=source)
        first = time.perf_counter() - t
        PreparedScene.reuse_casts = True  # what a still lidar's later frames do
        later = []
        for f in range(2, frames + 1):
            scene.frame_set(f)
            t = time.perf_counter()
            res, info = scan_lidar(lidar, f, session=session, source=source)
            later.append(time.perf_counter() - t)
        PreparedScene.reuse_casts = False
        dg = bpy.context.evaluated_depsgraph_get()
        rmax = info["effects"]["range_m"][1] + MOVER_MARGIN_M
        from rls_addon.blender import extract as ex

        extract = {}
        for name, reader in (("every mesh read", None), ("session reader", source.meshes)):
            extract[name], _ = best(lambda: read_instances(dg, pose[:3, 3], rmax, {"LiDAR"},
                                                           reader=reader), 3)
        arrays, ex._attribute_arrays = ex._attribute_arrays, lambda mesh: None
        try:  # Blender's per-item accessors (older Blenders; what RLS read before)
            extract["every mesh read item by item"], _ = best(
                lambda: read_instances(dg, pose[:3, 3], rmax, {"LiDAR"}), 2)
        finally:
            ex._attribute_arrays = arrays
        # The same lidar driving along the street at 10 m/s (exact motion: every ray
        # from where the lidar was when it fired).
        fps = scene.render.fps / scene.render.fps_base
        for f, x in ((1, pose[0, 3]), (101, pose[0, 3] + 1000.0 / fps)):
            lidar.location.x = x
            lidar.keyframe_insert("location", index=0, frame=f)
        for fc in _fcurves(lidar):
            for kp in fc.keyframe_points:
                kp.interpolation = "LINEAR"
        drive, builds = [], session.builds
        for f in range(1, frames + 1):
            scene.frame_set(f)
            t = time.perf_counter()
            _, dinfo = scan_lidar(lidar, f, session=session, source=source)
            drive.append(time.perf_counter() - t)
        return {"first_s": first, "later_s": min(later), "reused": res.stats["static_cast_reused"],
                "extract_s": extract, "objects": info["objects_read"],
                "driving_s": drive, "driving_builds": session.builds - builds,
                "driving_moves": bool(dinfo["motion"].get("sensor_moves"))}
    finally:
        PreparedScene.reuse_casts = False
        for ob in list(bpy.data.objects):
            bpy.data.objects.remove(ob)
        for mesh in list(bpy.data.meshes):
            bpy.data.meshes.remove(mesh)
        rls_addon.unregister()


def _fcurves(obj):
    """The F-curves of an object's action (Blender 4.4+ keeps them in slot channelbags)."""
    from bpy_extras import anim_utils

    ad = obj.animation_data
    bag = anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot)
    return bag.fcurves


def frame_profile(scene, pattern, pose, preset, frames=5, top=10):
    """Where one default frame's time goes: cProfile over a few frames, the functions
    with the most own time (ms per frame). Waiting for the caster's worker threads shows
    as ``acquire``."""
    import cProfile
    import io
    import pstats

    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    prof = cProfile.Profile()
    prof.enable()
    for _ in range(frames):
        scan_frame(scene, pattern, pose, preset, ScanSettings())
    prof.disable()
    st = pstats.Stats(prof, stream=io.StringIO())
    rows = []
    for (fname, line, func), (_, ncalls, tt, ct, _) in st.stats.items():
        where = f"{Path(fname).name}:{line}({func})" if line else func
        rows.append({"function": where, "calls_per_frame": ncalls / frames,
                     "own_ms": tt * 1000 / frames, "cumulative_ms": ct * 1000 / frames})
    rows.sort(key=lambda r: -r["own_ms"])
    return rows[:top]


def ghosting_cost(scene, pattern, pose, preset, repeat=3):
    """Cost of ghost points from glossy surfaces: one frame with ghosting on and off
    (noise and dropout on), on a built ``PreparedScene``. Returns a line for the
    report, or None when this engine has no ghosting switch. Later work may extend it
    (ghost counts, glossy fraction of the scene)."""
    import dataclasses

    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    if "ghosting" not in {f.name for f in dataclasses.fields(ScanSettings)}:
        return None
    on, res_on = best(lambda: scan_frame(scene, pattern, pose, preset, ScanSettings()), repeat)
    off, res_off = best(lambda: scan_frame(scene, pattern, pose, preset,
                                           ScanSettings(ghosting=False)), repeat)
    ghosts = int(res_on.points["ghost"].sum()) if "ghost" in res_on.points.dtype.names else 0
    return (f"{preset.name} frame with {scene.backend}: ghosting on {on * 1000:.1f} ms, "
            f"off {off * 1000:.1f} ms (+{(on - off) * 1000:.1f} ms, {ghosts:,} ghost points)")


# ---- speed against accuracy: tessellation ---------------------------------------------

def _ray_sphere(o, d, c, r):
    oc = o - c
    b = d @ oc
    disc = b * b - (oc @ oc - r * r)
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    return np.where((disc >= 0) & (t > 0), t, np.inf)


def _ray_cylinder_side(o, d, c, r, h):
    """Distance to the side of a z-axis cylinder (inf when the first hit is not the side)."""
    oc = o[:2] - c[:2]
    dd = d[:, :2]
    a = np.einsum("ij,ij->i", dd, dd)
    b = dd @ oc
    cc = oc @ oc - r * r
    disc = b * b - a * cc
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (-b - np.sqrt(disc)) / a
    z = o[2] + t * d[:, 2]
    ok = (disc >= 0) & (t > 0) & (z >= c[2]) & (z <= c[2] + h)
    return np.where(ok, t, np.inf)


def tessellation_study(preset, levels):
    """Range error (vs the analytic surface) and frame time for a sphere and a cylinder
    tessellated ever finer, seen by one frame of ``preset``."""
    import bpy  # noqa: F401

    from bench.scene import cylinder, uv_sphere
    from rls_addon.core.casting import BVHCaster
    from rls_addon.core.casting.embree import EmbreeCaster
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.scene.geometry import SceneGeometry

    dirs = np.ascontiguousarray(preset.pattern().directions)
    origin = np.zeros(3)
    shapes = {
        "sphere r=4 m at 12 m": (lambda s: uv_sphere(s // 2, s, (4.0, 4.0, 4.0), (12.0, 0, 0)),
                                 lambda: _ray_sphere(origin, dirs, np.array([12.0, 0, 0]), 4.0)),
        "cylinder r=1 m at 8 m": (lambda s: cylinder(s, 1.0, 4.0, (6.0, -6.0, -2.0), caps=True),
                                  lambda: _ray_cylinder_side(origin, dirs, np.array([6.0, -6.0, -2.0]),
                                                             1.0, 4.0)),
    }
    rows = []
    for shape, (make, exact) in shapes.items():
        truth = exact()
        for s in levels:
            v, t = make(s)
            g = SceneGeometry(v, t, np.zeros(len(t)), np.zeros(len(t)))
            row = {"shape": shape, "segments": s, "triangles": int(len(t))}
            for name, factory in (("embree", EmbreeCaster), ("bvhtree", BVHCaster)):
                ps = PreparedScene(g, origin, 60.0, factory)
                sec, (dist, tri, _) = best(lambda: ps.cast(origin, dirs, 60.0), 2)
                row[f"{name}_s"] = sec
            both = np.isfinite(truth) & (tri >= 0)
            err = np.abs(dist[both] - truth[both])
            row.update(rays_on_shape=int(both.sum()), mean_err_m=float(err.mean()),
                       p99_err_m=float(np.percentile(err, 99)), max_err_m=float(err.max()),
                       sagitta_m=float((4.0 if "sphere" in shape else 1.0)
                                       * (1 - np.cos(np.pi / s))))
            rows.append(row)
            log(f"bench: tessellation {shape} {s}: mean {row['mean_err_m'] * 1000:.2f} mm")
    return rows


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
    charts = {"scaling": "bench_scaling.png", "tessellation": "bench_tessellation.png"}
    chart_scaling(res["triangles"], res["rays"], out / charts["scaling"])
    chart_tessellation(res["tessellation"], out / charts["tessellation"], "Pandar64")
    from bench import engine_costs as ec

    charts["motion"] = "bench_motion_substeps.png"
    charts["disks"] = "bench_infranuc_disks.png"
    ec.chart_motion(res["costs"]["motion"]["embree"], out / charts["motion"])
    ec.chart_disks(res["costs"]["disks"], out / charts["disks"])
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
    import bpy  # noqa: F401

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
    dev = devices_section(g, SENSOR_POSE, quick)
    p64, _ = preset_or_fallback("Pandar64", "hesai_pandar64")
    p128, _ = preset_or_fallback("Pandar128", "hesai_pandar128")
    pattern_s = min(fresh_pattern_time(p128) for _ in range(3))
    ray_rows = scaling_rays(g, SENSOR_POSE, p64, quick)
    hooks = {"ghosting cost": dev["ghosting"]}
    costs = engine_costs_section(g, SENSOR_POSE, p64, quick)
    log("bench: a still lidar in Blender (scene extraction included)")
    costs["blender"] = blender_section(g, SENSOR_POSE)
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
    tri_rows = scaling_triangles(SENSOR_POSE, p64, quick)
    mem = memory_section([100_000, 1_000_000] if quick else [100_000, 1_000_000, 4_000_000])
    levels = [8, 16, 32, 64, 128, 256] if quick else [8, 16, 32, 64, 128, 256, 512]
    tess = tessellation_study(p64, levels)
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
