"""The devices on the 1M-triangle street: each device's cast with every backend and
baseline, its whole frame (cold, without effects, a still sensor's later frames), the
rays a frame really casts, where a Pandar64 frame's time goes, what ghosting costs, and
the pattern's build time; the report's section *Devices on the 1M-triangle street*."""

import time
from pathlib import Path

import numpy as np

from bench.backends import Backends, CountingFactory
from bench.timing import best, log, mrays, ms

DEVICES = [("Pandar64", "hesai_pandar64"), ("Pandar128", "hesai_pandar128"),
           ("Livox Avia", "livox_avia"), ("RoboSense M1", "robosense_m1")]


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


def measure(geometry, pose, quick):
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


def section(dev, pattern_s):
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
