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
            _, info = scan_lidar(lidar, f, session=session, source=source)
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
        return {"first_s": first, "later_s": min(later), "reused": info["static_cast_reused"],
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


def chart_tessellation(rows, path, device):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    for shape in dict.fromkeys(r["shape"] for r in rows):
        rs = [r for r in rows if r["shape"] == shape]
        tri = [r["triangles"] for r in rs]
        l1, = ax1.loglog(tri, [r["mean_err_m"] * 1000 for r in rs], "o-", label=f"{shape}: mean")
        ax1.loglog(tri, [r["max_err_m"] * 1000 for r in rs], "^--", color=l1.get_color(),
                   label=f"{shape}: max")
        ax1.loglog(tri, [r["sagitta_m"] * 1000 for r in rs], ":", color=l1.get_color(),
                   alpha=0.6, label=f"{shape}: chord sagitta R(1-cos(pi/n))")
        for name, mk in (("embree", "o-"), ("bvhtree", "s--")):
            ax2.loglog([r[f"{name}_s"] * 1000 for r in rs], [r["mean_err_m"] * 1000 for r in rs],
                       mk, label=f"{shape}, {name}")
        for r in rs:
            ax2.annotate(str(r["segments"]), (r["embree_s"] * 1000, r["mean_err_m"] * 1000),
                         fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax1.set_xlabel("triangles in the shape")
    ax1.set_ylabel("range error vs analytic surface (mm)")
    ax1.set_title("Tessellation against range error")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=7)
    ax2.set_xlabel(f"time to cast one {device} frame (ms, incl. exact refinement)")
    ax2.set_ylabel("mean range error (mm)")
    ax2.set_title("Speed against accuracy (labels: segments)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def chart_scaling(tri_rows, ray_rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # colour by backend, line style and marker by variant: curves that coincide (Embree
    # and Open3D) stay visible, one dashed or dotted over the other
    names = [("embree", "Embree (RLS, all cores)", "C0", "o", "-"),
             ("embree_1t", "Embree (RLS, 1 thread)", "C0", "s", "--"),
             ("bvhtree", "BVHTree (RLS caster)", "C2", "D", "-"),
             ("bare ray_cast loop", "bare BVHTree loop", "C3", "v", "--"),
             ("open3d", "Open3D (all cores)", "C1", "^", ":"),
             ("open3d_1t", "Open3D (1 thread)", "C1", "x", "-.")]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5.4), layout="constrained")
    for key, label, colour, marker, ls in names:
        style = {"color": colour, "marker": marker, "ls": ls, "label": label, "markersize": 6,
                 "markerfacecolor": "none" if ls != "-" else colour}
        xs = [r["triangles"] for r in tri_rows if key in r["cast_s"]]
        ys = [r["cast_s"][key] * 1000 for r in tri_rows if key in r["cast_s"]]
        if xs:
            ax1.loglog(xs, ys, **style)
        xs = [r["rays"] for r in ray_rows if key in r["cast_s"]]
        ys = [r["rays"] / r["cast_s"][key] / 1e6 for r in ray_rows if key in r["cast_s"]]
        if xs:
            ax2.semilogx(xs, ys, **style)
    ax1.set_xlabel("triangles")
    ax1.set_ylabel("time for one Pandar64 frame (ms)")
    ax1.set_title("Cast time against scene size")
    ax2.set_xlabel("rays per call (1M-triangle street)")
    ax2.set_ylabel("million rays per second")
    ax2.set_title("Throughput against rays")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
    # one legend for both panels, below them: none of the curves is covered
    legend = {}
    for ax in (ax1, ax2):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(lab, h)
    fig.legend(list(legend.values()), list(legend), loc="outside lower center", ncol=3,
               fontsize=8, frameon=False)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---- report ---------------------------------------------------------------------------

def ms(s):
    return f"{s * 1000:.1f}"


def mrays(n, s):
    return f"{n / s / 1e6:.2f}"


def ratios(dev):
    """The three targets, from the device rows of this run."""
    out = {}
    rows = dev["rows"]
    # Embree vs Open3D, rays/s on the same rays, same thread count (all cores; 1 thread).
    r_all = [r["cast_s"]["open3d"] / r["cast_s"]["embree"] for r in rows if "open3d" in r["cast_s"]]
    r_one = [r["cast_s"]["open3d_1t"] / r["cast_s"]["embree_1t"] for r in rows
             if "open3d_1t" in r["cast_s"]]
    out["embree_vs_open3d"] = min(r_all) if r_all else None
    out["embree_vs_open3d_1t"] = min(r_one) if r_one else None
    bare = lambda r: r["cast_s"]["bare ray_cast loop"]  # noqa: E731
    out["bvh_pipeline_vs_bare"] = max(r["frame_s"]["bvhtree"] / bare(r) for r in rows)
    out["bvh_caster_vs_bare"] = max(r["cast_s"]["bvhtree"] / bare(r) for r in rows)
    out["bvh_prepared_cast_vs_bare"] = max(r["prepared_cast_s"]["bvhtree"] / bare(r)
                                           for r in rows)
    out["bvh_frame_no_effects_vs_bare"] = max(r["frame_no_effects_s"]["bvhtree"] / bare(r)
                                              for r in rows)
    # Per ray actually cast (watertight re-checks and ghost rays are extra rays).
    out["bvh_frame_per_ray_vs_bare"] = max(
        r["frame_s"]["bvhtree"] / (bare(r) * r["rays_cast"]["frame"] / r["rays"]) for r in rows)
    p64 = next((r for r in rows if r["device"] == "Pandar64"), rows[0])
    out["pandar64_realtime"] = (1.0 / p64["frequency_hz"]) / p64["frame_s"]["embree"]
    out["pandar64_realtime_no_effects"] = ((1.0 / p64["frequency_hz"])
                                           / p64["frame_no_effects_s"]["embree"])
    out["pandar64_realtime_cast_only"] = (1.0 / p64["frequency_hz"]) / p64["cast_s"]["embree"]
    return out


def write_report(path, info, dev, tri_rows, ray_rows, mem, tess, pattern_s, charts, hooks,
                 total_s, costs):
    r = ratios(dev)
    same, motion = costs["same_rays"], costs["motion"]
    L = []
    L += _header_lines(info, dev, total_s)
    L += _targets_lines(r, same, motion)
    L += _devices_lines(dev, pattern_s)
    L += _scaling_lines(charts, tri_rows, ray_rows)
    L += _memory_lines(mem)
    L += _accuracy_lines(charts, tess)
    L += _blender_lines(costs)
    L += _motion_lines(charts, motion)
    L += _disks_lines(charts, costs, same, hooks)
    L += _others_lines(costs)
    L += _embree_lines()
    Path(path).write_text("\n".join(L))
    return r


def _header_lines(info, dev, total_s):
    """Title, machine, versions, scene."""
    L = []
    L.append("# Benchmarks\n")
    L.append("Written by `make bench` (`bench/run.py`); every number below comes from one run. "
             "Times are the best of 2-3 repeats; the machine may be shared with other work, "
             "so treat small differences as noise.\n")
    v = info["versions"]
    L.append(f"- Machine: {info['cpu']}, {info['cores']} cores, "
             f"{info['memory_gib']:.1f} GiB memory, {info['os']}")
    L.append(f"- Date: {info['date']}; whole run {total_s / 60:.1f} min; load average "
             f"{info['loadavg_start']:.2f} at the start, {info.get('loadavg_end', 0):.2f} at the end "
             f"(above ~0.3, other work shared the cores and multi-thread numbers suffer)")
    L.append("- Versions: " + ", ".join(f"{k} {val}" for k, val in v.items()))
    L.append(f"- Scene: procedural street (`bench/scene.py`), {dev['triangles']:,} triangles "
             "within range of a roof-mounted sensor 2 m above the road\n")
    for n in dev["notes"]:
        L.append(f"> **Preset fallback:** {n}\n")
    return L


def ok(v, target, higher=True):
    """A target's verdict: met, missed, or n/a when it was not measured."""
    if v is None:
        return "n/a"
    return "**met**" if (v >= target if higher else v <= target) else "**missed**"


def _targets_lines(r, same, motion):
    """The targets measured as ratios in this run."""
    L = []
    L.append("## Targets (ratios from this run)\n")
    L.append("| target | measured | |")
    L.append("|---|---|---|")
    L.append(f"| Embree rays/s >= 0.7x Open3D's, same rays, all cores (worst device) | "
             f"{r['embree_vs_open3d']:.2f}x | {ok(r['embree_vs_open3d'], 0.7)} |"
             if r["embree_vs_open3d"] is not None else "| Embree vs Open3D | n/a | |")
    if r["embree_vs_open3d_1t"] is not None:
        L.append(f"| (same, 1 thread each) | {r['embree_vs_open3d_1t']:.2f}x | "
                 f"{ok(r['embree_vs_open3d_1t'], 0.7)} |")
    L.append(f"| BVHTree pipeline: a default Pandar64 frame (`scan_frame` on a built "
             f"`PreparedScene`) <= 1.25x the bare `ray_cast` loop over the same rays (the "
             f"{same['rays']:,} rays the frame cast, each with its origin) | "
             f"{same['ratio']:.2f}x | {ok(same['ratio'], 1.25, False)} |")
    for name in ("bvhtree", "embree"):
        m = motion[name]
        L.append(f"| Exact motion distortion, ten moving cars, Pandar64, {name}: <= 1.3x the "
                 f"snapshot scan | {m['exact_vs_snapshot']:.2f}x | "
                 f"{ok(m['exact_vs_snapshot'], 1.3, False)} |")
    L.append(f"| (BVHTree frame against the bare loop over the pattern's rays only, worst "
             f"device) | {r['bvh_pipeline_vs_bare']:.2f}x | |")
    L.append(f"| (BVHTree: caster alone / `PreparedScene.cast` / frame without ghosting, noise "
             f"and dropout, each against the bare loop) | {r['bvh_caster_vs_bare']:.2f}x / "
             f"{r['bvh_prepared_cast_vs_bare']:.2f}x / {r['bvh_frame_no_effects_vs_bare']:.2f}x"
             f" | |")
    L.append(f"| Pandar64 frame on the 1M-triangle street >= 4x faster than real time (10 Hz), "
             f"Embree | {r['pandar64_realtime']:.1f}x | {ok(r['pandar64_realtime'], 4.0)} |")
    L.append(f"| (Pandar64 with Embree: frame without ghosting, noise and dropout / cast "
             f"alone) | {r['pandar64_realtime_no_effects']:.1f}x / "
             f"{r['pandar64_realtime_cast_only']:.1f}x | |\n")
    return L


def _devices_lines(dev, pattern_s):
    """Every device on the 1M-triangle street: casts, frames, still sensors, rays cast, profile, build times."""
    L = []
    L.append("## Devices on the 1M-triangle street\n")
    L.append("Cast only (ms per frame; in brackets million rays/s). `embree` is RLS's Embree "
             "backend on all cores, `embree 1t` on one thread; `bvhtree` is RLS's BVHTree "
             "caster; `bare loop` is `for d in dirs: tree.ray_cast(o, d, max)` over "
             "prepared lists; Open3D is `RaycastingScene.cast_rays` (`nthreads=0`: all "
             "cores, and 1).\n")
    L.append("| device | rays | embree | embree 1t | open3d | open3d 1t | bvhtree | bare loop |")
    L.append("|---|---|---|---|---|---|---|---|")
    for row in dev["rows"]:
        c, n = row["cast_s"], row["rays"]
        cell = lambda k: f"{ms(c[k])} ({mrays(n, c[k])})" if k in c else "n/a"  # noqa: E731
        L.append(f"| {row['device']} | {n:,} | {cell('embree')} | {cell('embree_1t')} | "
                 f"{cell('open3d')} | {cell('open3d_1t')} | {cell('bvhtree')} | "
                 f"{cell('bare ray_cast loop')} |")
    L.append("")
    L.append("Whole frame (ms): `scan_frame` on a `PreparedScene` built once, default "
             "settings (watertight re-check of misses, exact float64 refinement, ghosting, "
             "noise, dropout, intensity, points); *no effects* is the same with ghosting, "
             "noise and dropout off; *prepared cast* is `PreparedScene.cast` alone (primary "
             "cast, watertight re-check, refinement).\n")
    L.append("| device | Hz | points | Embree: prepared cast | no effects | frame | x real time "
             "| BVHTree: prepared cast | no effects | frame | x real time | BVHTree frame / "
             "bare loop |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for row in dev["rows"]:
        f, period = row["frame_s"], 1.0 / row["frequency_hz"]
        pc, fb = row["prepared_cast_s"], row["frame_no_effects_s"]
        L.append(f"| {row['device']} | {row['frequency_hz']:g} | {row['points']:,} | "
                 f"{ms(pc['embree'])} | {ms(fb['embree'])} | {ms(f['embree'])} | "
                 f"{period / f['embree']:.1f} | {ms(pc['bvhtree'])} | {ms(fb['bvhtree'])} | "
                 f"{ms(f['bvhtree'])} | {period / f['bvhtree']:.1f} | "
                 f"{f['bvhtree'] / row['cast_s']['bare ray_cast loop']:.2f} |")
    L.append("")
    if all("frame_still_s" in row for row in dev["rows"]):
        L.append("Every frame above is *cold*: it casts the whole static street. A sensor that "
                 "does not move (a pole, a traffic light) casts the same rays into the same "
                 "static scene every frame, so from its second frame on the prepared scene "
                 "gives back its kept static cast (`PreparedScene.cast`, byte-identical to "
                 "casting again: `tests/core/test_static_reuse.py`); ghost rays, noise, "
                 "dropout and points are still made anew for every frame. Default settings, "
                 "ms per frame:\n")
        L.append("| device | Embree: cold frame | still sensor, later frames | x real time "
                 "| BVHTree: cold frame | still sensor, later frames | x real time |")
        L.append("|---|---|---|---|---|---|---|")
        for row in dev["rows"]:
            f, s, period = row["frame_s"], row["frame_still_s"], 1.0 / row["frequency_hz"]
            L.append(f"| {row['device']} | {ms(f['embree'])} | {ms(s['embree'])} | "
                     f"{period / s['embree']:.1f} | {ms(f['bvhtree'])} | {ms(s['bvhtree'])} | "
                     f"{period / s['bvhtree']:.1f} |")
        L.append("")
    L.append("Rays actually cast per frame (counted by wrapping the caster): the pattern's "
             "rays, then `PreparedScene.cast` adds the watertight re-check of misses against "
             "padded cluster boxes and nudged re-casts, and the frame adds ghost rays from "
             "glossy hits (car paint and windows are glossy in this street).\n")
    L.append("| device | pattern rays | `PreparedScene.cast` | whole frame | extra |")
    L.append("|---|---|---|---|---|")
    for row in dev["rows"]:
        c = row["rays_cast"]
        L.append(f"| {row['device']} | {c['pattern']:,} | {c['prepared_cast']:,} | "
                 f"{c['frame']:,} | {c['frame'] / c['pattern'] - 1:+.0%} |")
    L.append("")
    for name, prof in dev.get("profile", {}).items():
        L.append(f"Where a default Pandar64 frame's time goes with {name} (cProfile, own time "
                 "per frame; profiling adds some overhead):\n")
        L.append("| function | calls per frame | own ms | cumulative ms |")
        L.append("|---|---|---|---|")
        for p in prof:
            L.append(f"| `{p['function']}` | {p['calls_per_frame']:g} | {p['own_ms']:.1f} | "
                     f"{p['cumulative_ms']:.1f} |")
        L.append("")
    L.append("Build times on the 1M-triangle street (s): "
             + ", ".join(f"{k} {val:.2f}" for k, val in dev["build_s"].items()) + "\n")
    L.append(f"Pattern generation, one Pandar128 frame from scratch: {pattern_s * 1000:.1f} ms\n")
    return L


def _scaling_lines(charts, tri_rows, ray_rows):
    """A frame's cast against scene size and rays per call."""
    L = []
    L.append("## Scaling\n")
    L.append(f"![scaling]({charts['scaling']})\n")
    L.append("One Pandar64 frame (ms) against scene size:\n")
    keys = ["embree", "embree_1t", "open3d", "open3d_1t", "bvhtree", "bare ray_cast loop"]
    L.append("| triangles | " + " | ".join(keys) + " | build embree (s) | build bvhtree (s) | "
             "build open3d (s) |")
    L.append("|---" * (len(keys) + 4) + "|")
    for row in tri_rows:
        c, b = row["cast_s"], row["build_s"]
        L.append(f"| {row['triangles']:,} | " + " | ".join(ms(c[k]) if k in c else "n/a"
                                                          for k in keys)
                 + f" | {b.get('embree', float('nan')):.2f} | {b.get('bvhtree', float('nan')):.2f}"
                 f" | {b.get('open3d', float('nan')):.2f} |")
    L.append("")
    L.append("Million rays per second against rays per call (1M-triangle street, Pandar64 "
             "directions sampled):\n")
    L.append("| rays | " + " | ".join(keys) + " |")
    L.append("|---" * (len(keys) + 1) + "|")
    for row in ray_rows:
        c = row["cast_s"]
        L.append(f"| {row['rays']:,} | " + " | ".join(mrays(row["rays"], c[k]) if k in c
                                                       else "n/a" for k in keys) + " |")
    L.append("")
    return L


def _memory_lines(mem):
    """Peak memory per backend."""
    L = []
    L.append("## Peak memory\n")
    L.append("One subprocess per case: generate the street, keep its sensor-centred arrays, "
             "build the backend and cast one Pandar64 frame; resident memory sampled every "
             "2 ms. *Added* is the peak minus the resident memory just before the build; "
             "*kept* is what stays after the cast.\n")
    L.append("| backend | triangles | RSS before (MiB) | peak (MiB) | peak added (MiB) | "
             "kept (MiB) |")
    L.append("|---|---|---|---|---|---|")
    for m in mem:
        L.append(f"| {m['backend']} | {m['triangles']:,} | {m['before_mib']:.0f} | "
                 f"{m['peak_mib']:.0f} | {m['added_mib']:.0f} | "
                 f"{m['after_mib'] - m['before_mib']:.0f} |")
    L.append("")
    return L


def _accuracy_lines(charts, tess):
    """Tessellation error against time."""
    L = []
    L.append("## Speed against accuracy\n")
    L.append(f"![tessellation]({charts['tessellation']})\n")
    L.append("Curved surfaces tessellated with n segments (UV sphere with n/2 rings); range "
             "error of Pandar64 rays against the analytic surface, and the time to cast the "
             "frame. The mean error falls as n^-2 like the chord sagitta R(1 - cos(pi/n)) (the "
             "radial gap between facets and surface); along oblique rays it is a small "
             "multiple of it, and the maximum comes from rays grazing the silhouette. The "
             "ray caster adds nothing measurable on top of the tessellation (ranges are "
             "refined exactly against the hit facet), and finer tessellation costs little "
             "time: traversal grows with log(triangles).\n")
    L.append("| shape | segments | triangles | rays on shape | mean error (mm) | max error (mm) "
             "| sagitta (mm) | Embree (ms) | BVHTree (ms) |")
    L.append("|---|---|---|---|---|---|---|---|---|")
    for t in tess:
        L.append(f"| {t['shape']} | {t['segments']} | {t['triangles']:,} | {t['rays_on_shape']:,}"
                 f" | {t['mean_err_m'] * 1000:.3f} | {t['max_err_m'] * 1000:.3f} | "
                 f"{t['sagitta_m'] * 1000:.3f} | {ms(t['embree_s'])} | {ms(t['bvhtree_s'])} |")
    L.append("")
    return L


def _blender_lines(costs):
    """A still and a driving lidar in Blender, extraction included."""
    L = []
    b = costs.get("blender")
    if b:
        L.append("## In Blender\n")
        L.append(f"The same street as {b['objects']} Blender mesh objects (`bench/scene.py:"
                 "add_to_blender`; labelled, without materials, so nothing is glossy and "
                 "no ghost rays are cast) and a Pandar64 lidar standing still at the same pose, "
                 "scanned frame after frame through the add-on's scan session (Embree, "
                 "default settings, scene extraction included). Extraction copies "
                 "positions, corners and face materials out of Blender's attribute arrays "
                 "(this street is all triangles, so that is all it reads; meshes with "
                 "quads or n-gons also need Blender's triangulation, read per triangle, "
                 "which the session's `extract.MeshReader` skips for a mesh unchanged "
                 "since it was last read). Later frames key the static scene by mesh ids "
                 "instead of joining and digesting its triangles, and reuse the static "
                 "cast.\n")
        L.append("| | ms |")
        L.append("|---|---|")
        L.append(f"| first frame (extraction, Embree build, scan) | {ms(b['first_s'])} |")
        L.append(f"| later frame, best of five (static cast reused: {b['reused']}) | "
                 f"{ms(b['later_s'])} |")
        for name, s in b["extract_s"].items():
            L.append(f"| extraction alone, {name} | {ms(s)} |")
        if "driving_s" in b:
            d = b["driving_s"]
            L.append(f"| the lidar driving at 10 m/s (exact motion): first frame, second "
                     f"frame (the scene prepared wider, `DRIVING_SLACK`), later frames best "
                     f"| {ms(d[0])}, {ms(d[1])}, {ms(min(d[2:]))} "
                     f"({b['driving_builds']} builds in {len(d)} frames) |")
        L.append("")
    return L


def _motion_lines(charts, motion):
    """Exact motion against snapshot and sub-steps."""
    L = []
    m = motion["embree"]
    L.append("## Motion distortion\n")
    L.append(f"![motion]({charts['motion']})\n")
    L.append(f"Ten cars nearest the sensor drive at {m['speed_mps']:g} m/s through the "
             "1M-triangle street during a Pandar64 sweep (10 Hz). *Snapshot* freezes them at "
             "the sweep start inside the static structure; *exact* casts every ray at its own "
             "time: with BVHTree the cars in their own frames (one shared structure built "
             "once), with Embree the static street and every car as instances of one "
             "traversal, each car moved by its track at time steps, every hit refined at "
             "the ray's own time (rls_addon/core/world/instancing.py); *N "
             "sub-steps* is the paper's method as a simulator runs it: the cars are placed "
             "and rebuilt at the middle of each of N sub-sweeps. Error: distance of car "
             "points (ghosts excluded) from the car surface where the car really was at the "
             "point's own time.\n")
    L.append("| mode | backend | frame (ms) | mean error (mm) | max error (mm) |")
    L.append("|---|---|---|---|---|")
    for name in ("bvhtree", "embree"):
        mm = motion[name]
        L.append(f"| snapshot | {name} | {ms(mm['snapshot_s'])} | | |")
        L.append(f"| exact | {name} | {ms(mm['exact_s'])} | {mm['exact_mean_err_m'] * 1000:.4f} |"
                 f" {mm['exact_max_err_m'] * 1000:.4f} |")
        if "exact_still_s" in mm:
            L.append(f"| exact, still sensor's later frames (static cast reused, cars traced) "
                     f"| {name} | {ms(mm['exact_still_s'])} | | "
                     f"{mm['exact_still_max_err_m'] * 1000:.4f} |")
    for row in m["substeps"]:
        L.append(f"| {row['substeps']} sub-steps | embree | {ms(row['seconds'])} | "
                 f"{row['mean_err_m'] * 1000:.1f} | {row['max_err_m'] * 1000:.1f} |")
    L.append(f"\n({m['car_points']:,} car points per frame; the bound v*T/(2N) is "
             f"{m['speed_mps'] * 0.1 / 2 * 1000:.0f} mm / N.)\n")
    return L


def _disks_lines(charts, costs, same, hooks):
    """InfraNUC's disk count against spread and time; the same-rays measurement; hooks."""
    L = []
    L.append("## InfraNUC: disk count against spread and time\n")
    L.append(f"![disks]({charts['disks']})\n")
    L.append("A LiDAR-like cloud (density falling with distance from a pole; 200,000 points "
             "over a 20 x 30 m region, whole disks of 0.7 m inside): InfraNUC over 12 seeds "
             "of the disk placement.\n")
    L.append("| disks | mean InfraNUC | spread (std) | time per estimate (ms) |")
    L.append("|---|---|---|---|")
    for row in costs["disks"]:
        L.append(f"| {row['disks']:,} | {row['mean']:.4f} | {row['spread']:.4f} | "
                 f"{row['seconds'] * 1000:.1f} |")
    L.append("")
    L.append(f"Same-rays measurement: the default Pandar64 frame cast {same['rays']:,} rays "
             f"({same['pattern_rays']:,} from the pattern; the rest are watertight re-checks "
             f"and ghost rays); bare loop over them {ms(same['bare_s'])} ms, frame "
             f"{ms(same['frame_s'])} ms.\n")
    for name, val in hooks.items():
        if val:
            L.append(f"- {name}: {val}")
    L.append("")
    return L


def _others_lines(costs):
    """The sections the other bench modules write."""
    L = []
    if costs.get("frame_costs"):
        from bench import frame_costs

        L.extend(frame_costs.report_lines(costs["frame_costs"]))
    if costs.get("effect_costs"):
        from bench import effect_costs

        L.extend(effect_costs.section(costs["effect_costs"]))
    if costs.get("study_costs"):
        from bench import study_costs

        L.extend(study_costs.section(costs["study_costs"]))
    if costs.get("scale_out"):
        from bench import scale_out

        L.extend(scale_out.section(costs["scale_out"]))
    return L


def _embree_lines():
    """How the Embree backend runs."""
    L = []
    L.append("## How the Embree backend runs\n")
    L.append("embreex 4.4.0.post1's own `EmbreeScene.run` casts one ray at a time and holds "
             "the GIL for the whole call (measured: two threads take as long as one). RLS "
             "builds its own Embree scene through `ctypes` on the library inside the embreex "
             "wheel and casts 16-ray packets with `rtcIntersect16`. A probe packet checks "
             "the packet layout once per process. The packets are cast by a small C loop "
             "(`rls_addon/core/native/c/embree_loop.c`, compiled by `tools/build_native.py` and "
             "shipped in the Linux zip) on its own threads in one `ctypes` call, so Python "
             "waits without the GIL; without the compiled loop, packets are cast from a "
             "Python thread pool, which hands the GIL back and forth every 16 rays and "
             "scales poorly on this virtual machine; without embreex, BVHTree is used with a "
             "notice. Robust mode (rays through shared edges and vertices never slip "
             "through) costs about 12%.\n")
    L.append("Exact range refinement, the watertight re-check of misses and the per-hit "
             "stage (intensity, noise, dropout, point records) run compiled in the loop's "
             "threads (`native/c/embree_loop.c`, `native/c/points.c`), with the numpy "
             "references compared byte for byte in the tests; what a cold frame costs "
             "beyond its cast is in *A frame against its cast* above (ghost rays are a "
             "second cast; the rest is the Python between the stages), and the profile "
             "above lists it by function.\n")
    return L


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
    info["loadavg_end"] = os.getloadavg()[0]
    return {"machine": info, "devices": dev, "triangles": tri_rows, "rays": ray_rows,
            "memory": mem, "tessellation": tess, "pattern_s": pattern_s, "hooks": hooks,
            "costs": costs, "seconds": time.perf_counter() - t_start}


if __name__ == "__main__":
    main()
