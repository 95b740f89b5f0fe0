"""What a frame costs beyond its cast (issue 18), on two scenes: the 1M-triangle street
and a small open-sky scene (``scene.open_sky_geometry``: half the rays to the sky).

For each scene and the Pandar64 preset (default settings):
- Embree: the cast alone (the pattern's rays into the prepared triangles, no re-check,
  no refinement) against a cold frame (``scan_frame``, nothing reused) and a still
  sensor's later frame (its static cast reused); the same cold frame with the numpy
  references (``assemble.compiled``, ``ghost.compiled``, ``returns.compiled`` and the
  re-check's ``compiled`` off) for the gain;
- BVHTree: the frame against the bare ``ray_cast`` loop over the pattern's rays.
End to end: ``rls scan --frames`` of a LiDAR driving across the open-sky scene (exact
motion, files written), wall time per frame after the first, against its cast alone.

Run alone: ``python bench/frame_costs.py [--quick]`` (prints JSON).
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def frame_casts(scene, pattern, pose, preset, settings, frame):
    """A function that makes only the casts a default frame makes, as the frame makes
    them: the pattern's rays through ``World.start`` (watertight re-check, float64
    refinement), then the ghost rays of the glossy returns the frame's own seeded draws
    send on (``ghost.aim``); and how many ghost rays that is."""
    from rls_addon.core.physics import effects, ghost
    from rls_addon.core.scan.frame import sensor_axes
    from rls_addon.core.scan.device_values import device_values
    from rls_addon.core.world.world import World

    rmin, rmax = device_values(preset, settings).range_m
    origin, rot = sensor_axes(pose)
    origins, dirs = origin.reshape(1, 3), pattern.rotated(rot)
    times = pattern.times
    world = World(scene, [])
    dist, body, tri, normals = world.start(origins, dirs, times, rmax)()
    valid, surface = world.returns(dist, body, tri, rmin, rmax)
    _, ghost_rng = effects.scan_rng(settings.seed, "sensor", frame)
    aim = ghost.aim(valid, surface,
                    ghost.glossy_tables(scene.geometry, ghost.glossy_labels()),
                    ghost_rng.random(len(dirs)), dist, dirs, normals, origins)

    def casts():
        world.start(origins, dirs, times, rmax)()
        if len(aim.chosen):
            world.start(aim.start, aim.r, times[aim.chosen], rmax, watertight=False)()

    return casts, len(aim.chosen)


def scene_ratios(geometry, pose, preset, repeat=7, bvh_repeat=2):
    """The ratios of one scene (seconds and ratios, see the module docstring)."""
    import bpy  # noqa: F401  (mathutils)

    from bench.baselines import bare_loop
    from rls_addon.core.physics import assemble, ghost
    from rls_addon.core.world import returns
    from rls_addon.core.world.bodies import PreparedScene
    from rls_addon.core.casting import BVHCaster
    from rls_addon.core.casting.embree import EmbreeCaster
    from rls_addon.core.scan.frame import scan_frame
    from rls_addon.core.scan.settings import ScanSettings

    pattern = preset.pattern()
    rmax = preset.range.max_m
    origin = pose[:3, 3]
    settings = ScanSettings()
    out = {"rays": len(pattern), "triangles": int(geometry.triangle_count)}
    scene = PreparedScene(geometry, origin, rmax, EmbreeCaster)
    scene.reuse_casts = False
    dirs = np.ascontiguousarray(pattern.directions @ pose[:3, :3].T)
    raw = EmbreeCaster(scene.vertices, scene.triangles)
    zero = np.zeros((1, 3))
    frames = iter(range(10_000))

    def frame():
        return scan_frame(scene, pattern, pose, preset, settings, frame=next(frames))

    casts, ghost_rays = frame_casts(scene, pattern, pose, preset, settings, 0)
    # Taking turns, so that a burst of load on a shared machine hits all alike.
    cast = cold = numpy_cold = casts_s = float("inf")
    for _ in range(3):
        cast = min(cast, _best(lambda: raw.cast(zero, dirs, rmax), repeat))
        casts_s = min(casts_s, _best(casts, repeat))
        cold = min(cold, _best(frame, repeat))
        scene.caster.compiled = assemble.compiled = ghost.compiled = returns.compiled = False
        try:
            numpy_cold = min(numpy_cold, _best(frame, max(2, repeat // 2)))
        finally:
            scene.caster.compiled = assemble.compiled = ghost.compiled = returns.compiled = True
    scene.reuse_casts = True
    frame()  # the first frame casts and keeps its static cast
    still = _best(frame, repeat)
    scene.reuse_casts = False
    res = frame()
    out.update(points=int(len(res.points)), cast_s=cast, frame_cold_s=cold,
               frame_casts_s=casts_s, casts_over_cast=casts_s / cast, ghost_rays=ghost_rays,
               frame_still_s=still, frame_cold_numpy_s=numpy_cold,
               cold_over_cast=cold / cast, still_over_cast=still / cast,
               numpy_over_cast=numpy_cold / cast,
               cold_realtime=(1.0 / preset.frequency_hz) / cold)
    bscene = PreparedScene(geometry, origin, rmax, BVHCaster)
    bscene.reuse_casts = False
    loop = bare_loop(bscene.caster.primary.tree, dirs, rmax)
    bare = bvh = float("inf")
    for _ in range(2):
        bare = min(bare, _best(loop, bvh_repeat))
        bvh = min(bvh, _best(lambda: scan_frame(bscene, pattern, pose, preset, settings),
                             bvh_repeat))
    out.update(bvh_bare_loop_s=bare, bvh_frame_s=bvh, bvh_over_bare=bvh / bare)
    return out


BUILD_DRIVE = r"""
import sys, bpy
sys.path.insert(0, sys.argv[1])
import rls_addon
bpy.ops.wm.read_factory_settings(use_empty=True)
rls_addon.register()
from bench.scene import open_sky_geometry, add_to_blender
scene = bpy.context.scene
scene.name = "sky"
scene.render.fps, scene.render.fps_base = 10, 1.0
add_to_blender(open_sky_geometry(), scene)
lidar = bpy.data.objects.new("LiDAR", None)
scene.collection.objects.link(lidar)
lidar.rls_lidar.is_lidar, lidar.rls_lidar.preset_id = True, "hesai_pandar64"
for frame, x in ((1, -40.0), (81, 40.0)):  # 10 m/s at 10 frames per second
    lidar.location = (x, 0.0, 5.0)
    lidar.keyframe_insert("location", frame=frame)
from bpy_extras import anim_utils
ad = lidar.animation_data
for fc in anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot).fcurves:
    for kp in fc.keyframe_points:
        kp.interpolation = "LINEAR"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
"""


def driving_end_to_end(frames=21, repeat=2):
    """Wall seconds per frame after the first of ``rls scan`` driving over the open-sky
    scene: (run of ``frames`` frames - run of one frame) / (frames - 1), best of
    ``repeat``, each run a fresh process as a user runs it."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with tempfile.TemporaryDirectory(prefix="rls-drive-") as tmp:
        blend = Path(tmp) / "sky.blend"
        subprocess.run([sys.executable, "-c", BUILD_DRIVE, str(ROOT), str(blend)], check=True,
                       capture_output=True, timeout=600)

        def run(last):
            t = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "rls_addon", "scan", str(blend),
                                   "--frames", f"1-{last}", "--out", str(Path(tmp) / "out"),
                                   "--workers", "1", "--overwrite"], env=env, cwd=ROOT,
                                  capture_output=True, text=True, timeout=1200)
            if proc.returncode != 0:
                raise RuntimeError(proc.stderr[-2000:])
            return time.perf_counter() - t, json.loads(proc.stdout)

        one = min(run(1)[0] for _ in range(repeat))
        many, summary = min((run(frames) for _ in range(repeat)), key=lambda r: r[0])
    per_frame = (many - one) / (frames - 1)
    scan_s = [o["seconds"] for o in summary["outputs"][1:]]
    return {"frames": frames, "one_frame_run_s": one, "run_s": many,
            "per_frame_s": per_frame, "scan_step_median_s": float(np.median(scan_s)),
            "points": summary["points"]}


def measure(street=None, quick=False):
    """Both scenes and the end-to-end drive; ``street``: the 1M street if built."""
    from bench.scene import OPEN_SKY_POSE, SENSOR_POSE, open_sky_geometry, street_geometry
    from rls_addon.core.device.presets import get_preset

    preset = get_preset("hesai_pandar64")
    rep = 3 if quick else 7
    out = {"open_sky": scene_ratios(open_sky_geometry(), OPEN_SKY_POSE, preset, rep)}
    if street is None:
        street = street_geometry(300_000 if quick else 1_000_000)
    out["street"] = scene_ratios(street, SENSOR_POSE, preset, rep)
    drive = driving_end_to_end(11 if quick else 21)
    drive["cast_s"] = out["open_sky"]["cast_s"]
    drive["per_frame_over_cast"] = drive["per_frame_s"] / drive["cast_s"]
    out["driving"] = drive
    out["loadavg"] = os.getloadavg()
    return out


def report_lines(r):
    """Markdown of ``measure``'s result for docs/benchmarks.md."""
    def ms(s):
        return f"{s * 1e3:.1f} ms"

    lines = ["## A frame against its cast (issue 18)\n",
             "Pandar64, default settings (watertight re-check, float64 refinement, ghosts, "
             "noise, dropout). *Cast* is Embree alone on the pattern's rays; the frame's "
             "re-check and per-hit stage run compiled (`native/c/embree_loop.c`, "
             "`native/c/points.c`); *numpy* is the same frame on the numpy references "
             "(same bytes). BVHTree is held to the bare `ray_cast` loop over the "
             "pattern's rays.\n",
             "*The frame's casts* are the casts a cold frame makes, timed alone: the "
             "pattern's rays with the watertight re-check and refinement, then the ghost "
             "rays its glossy returns send on (the frame's own seeded choice); what they "
             "leave below the target is all the rest of the frame may take.\n",
             "| scene | cast | the frame's casts | cold frame | still-sensor frame | "
             "numpy cold frame | cold / real time | BVHTree frame / bare loop |",
             "|---|---|---|---|---|---|---|---|"]
    targets = {"street": ("<= 1.3x", ">= 4.5x"), "open_sky": ("<= 1.6x", "")}
    for name, label in (("street", "1M street"), ("open_sky", "open sky")):
        s = r[name]
        lines.append(
            f"| {label} ({s['triangles']:,} triangles) | {ms(s['cast_s'])} | "
            f"{ms(s['frame_casts_s'])}, {s['casts_over_cast']:.2f}x "
            f"({s['ghost_rays']:,} ghost rays) | {ms(s['frame_cold_s'])}, **{s['cold_over_cast']:.2f}x** (target "
            f"{targets[name][0]}) | {ms(s['frame_still_s'])}, {s['still_over_cast']:.2f}x | "
            f"{ms(s['frame_cold_numpy_s'])}, {s['numpy_over_cast']:.2f}x | "
            f"{s['cold_realtime']:.1f}x {targets[name][1]} | "
            f"{ms(s['bvh_frame_s'])} / {ms(s['bvh_bare_loop_s'])} = "
            f"**{s['bvh_over_bare']:.2f}x** (target <= 1.25x) |")
    d = r["driving"]
    lines += ["",
              f"End to end, `rls scan --frames 1-{d['frames']}` of a LiDAR driving at 10 m/s "
              f"over the open-sky scene (exact motion, PCD and sidecars written, one "
              f"process): {ms(d['per_frame_s'])} wall per frame after the first, "
              f"**{d['per_frame_over_cast']:.1f}x** the frame's cast alone (target <= 2x); "
              f"the frame itself (`scan_frame`, the seconds the run reports per output) "
              f"took {ms(d['scan_step_median_s'])} (median); the rest of a step is the "
              f"sweep sampled through Blender (9 sub-frame states), the sidecar's pose "
              f"knots, reading the scene and waiting for the previous frame's files "
              f"(written on a thread of their own, with fsync).",
              f"Load average at the end: {r['loadavg'][0]:.2f}.\n"]
    return lines


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    res = measure(quick=quick)
    print(json.dumps(res, indent=1, default=float))
    print("\n".join(report_lines(res)))
