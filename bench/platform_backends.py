"""Measure the ray-casting backends each platform's zip could bundle, on this Linux
machine (the same PyPI packages run here): the numbers behind docs/platforms.md.

    .venv/bin/python bench/platform_backends.py [--triangles 1000000]
        [--embree2 DIR] [--warp DIR]

One Pandar64 frame (115,200 rays) from the benchmark street's sensor pose, on the
procedural street (bench/scene.py), every backend on the same sensor-centred
triangles and rays, each in its own process (embreex 2.17 and 4.4 share a module
name): build time, best-of-5 cast time, the share of rays whose triangle agrees with
Embree's, and for the backends RLS ships a whole cold frame through the engine
(watertight re-check, float64 refinement, ghosts, noise, dropout). pyemblite and
Open3D are in the venv (requirements-test.txt); the other candidates come from a
``pip install --no-deps --target DIR``:

    .venv/bin/pip install --no-deps --target /tmp/embree2 embreex==2.17.7.post7
    .venv/bin/pip install --no-deps --target /tmp/warp warp-lang==1.19.0
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _scene(triangles):
    sys.path.insert(0, str(ROOT))
    from bench.scene import SENSOR_POSE, street_geometry
    from rls_addon.core.scene.geometry import clean_for_casting
    from rls_addon.core.device.presets import get_preset

    g = street_geometry(triangles)
    p = get_preset("hesai_pandar64")
    dirs = np.ascontiguousarray(p.pattern().directions @ SENSOR_POSE[:3, :3].T)
    v, t, _, _ = clean_for_casting(g, SENSOR_POSE[:3, 3], p.range.max_m)
    return g, p, SENSOR_POSE, v, t, dirs, p.range.max_m


def _best(fn, k=5):
    out, best = None, float("inf")
    for _ in range(k):
        s = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - s)
    return best, out


def _warp_caster(v, t):
    import warp as wp

    wp.config.quiet = True
    wp.init()

    @wp.kernel
    def kcast(mesh: wp.uint64, dirs: wp.array(dtype=wp.vec3), tmax: float,
              dist: wp.array(dtype=float), tri: wp.array(dtype=int)):
        i = wp.tid()
        q = wp.mesh_query_ray(mesh, wp.vec3(0.0, 0.0, 0.0), dirs[i], tmax)
        if q.result:
            dist[i] = q.t
            tri[i] = q.face
        else:
            dist[i] = -1.0
            tri[i] = -1

    mesh = wp.Mesh(points=wp.array(v.astype(np.float32), dtype=wp.vec3, device="cpu"),
                   indices=wp.array(t.astype(np.int32).ravel(), dtype=int, device="cpu"))
    s = time.perf_counter()
    wp.load_module(device="cpu")
    compile_s = time.perf_counter() - s

    def cast(dirs, rmax):
        d = wp.array(dirs.astype(np.float32), dtype=wp.vec3, device="cpu")
        dist = wp.empty(len(dirs), dtype=float, device="cpu")
        tri = wp.empty(len(dirs), dtype=int, device="cpu")
        wp.launch(kcast, dim=len(dirs), inputs=[mesh.id, d, float(rmax), dist, tri], device="cpu")
        wp.synchronize_device("cpu")
        return tri.numpy().astype(np.int64)

    return cast, compile_s


def child(name, triangles):
    """Time one backend; print one JSON line."""
    g, preset, pose, v, t, dirs, rmax = _scene(triangles)
    o = np.zeros((1, 3))
    res = {"backend": name, "triangles": int(len(t)), "rays": int(len(dirs))}
    s = time.perf_counter()
    factory = None
    if name == "pyemblite":
        from rls_addon.core.casting import EmbliteCaster

        c = EmbliteCaster(v, t)
        res["describe"] = c.describe()
        cast = lambda: c.cast(o, dirs, rmax)[1]  # noqa: E731
        factory = EmbliteCaster
    elif name in ("embree", "embree_1t", "embree2"):
        from rls_addon.core.casting.embree import EmbreeCaster

        c = EmbreeCaster(v, t, threads=1 if name == "embree_1t" else None)
        res["describe"] = c.describe()
        cast = lambda: c.cast(o, dirs, rmax)[1]  # noqa: E731
        factory = EmbreeCaster
    elif name in ("open3d", "open3d_1t"):
        from rls_addon.core.casting import Open3DCaster

        c = Open3DCaster(v, t, threads=1 if name == "open3d_1t" else None)
        res["describe"] = c.describe()
        cast = lambda: c.cast(o, dirs, rmax)[1]  # noqa: E731
        factory = Open3DCaster
    elif name == "bvhtree":
        import bpy  # noqa: F401  (mathutils)
        from rls_addon.core.casting import BVHCaster

        c = BVHCaster(v, t)
        cast = lambda: c.cast(o, dirs, rmax)[1]  # noqa: E731
        factory = BVHCaster
    elif name == "warp":
        wcast, res["kernel_compile_s"] = _warp_caster(v, t)
        cast = lambda: wcast(dirs, rmax)  # noqa: E731
    else:
        raise SystemExit(f"unknown backend {name}")
    res["build_s"] = time.perf_counter() - s
    res["cast_s"], tri = _best(cast, 2 if name == "bvhtree" else 5)
    np.save(f"/tmp/rls-platform-bench-{name}.npy", tri)
    if factory is not None and name not in ("embree_1t", "open3d_1t"):
        from rls_addon.core.world.bodies import PreparedScene
        from rls_addon.core.scan.frame import scan_frame
        from rls_addon.core.scan.settings import ScanSettings

        PreparedScene.reuse_casts = False  # every frame cold, as bench/run.py times them
        scene = PreparedScene(g, pose[:3, 3], rmax, factory)
        pat = preset.pattern()
        res["frame_s"], _ = _best(lambda: scan_frame(scene, pat, pose, preset, ScanSettings()),
                                  2 if name == "bvhtree" else 5)
    print(json.dumps(res))


def wheel_sizes():
    sizes = {}
    for w in sorted((ROOT / "build" / "wheels").glob("*.whl")):
        sizes[w.name] = w.stat().st_size
    return sizes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--embree2", help="a --target dir holding embreex 2.17.7.post7")
    ap.add_argument("--warp", help="a --target dir holding warp-lang")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.triangles)
    runs = [("embree", None), ("embree_1t", None), ("pyemblite", None), ("open3d", None),
            ("open3d_1t", None), ("bvhtree", None)]
    if args.embree2:
        runs.append(("embree2", args.embree2))
    if args.warp:
        runs.append(("warp", args.warp))
    rows = []
    for name, extra in runs:
        env = dict(os.environ)
        if extra:
            env["PYTHONPATH"] = os.pathsep.join([extra, str(ROOT)])
            env.setdefault("WARP_CACHE_PATH", str(ROOT / "build" / "warp-cache"))
        proc = subprocess.run([sys.executable, __file__, "--child", name,
                               "--triangles", str(args.triangles)],
                              capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            print(f"{name}: failed\n{proc.stderr[-2000:]}", file=sys.stderr)
            continue
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    ref = np.load("/tmp/rls-platform-bench-embree.npy")
    bvh = next((r["cast_s"] for r in rows if r["backend"] == "bvhtree"), None)
    print(f"{rows[0]['triangles']:,} triangles, {rows[0]['rays']:,} rays "
          f"(one Pandar64 frame), {os.cpu_count()} cores\n")
    print("| backend | build | cast | Mrays/s | vs BVHTree | same triangle as Embree "
          "| cold frame |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        tri = np.load(f"/tmp/rls-platform-bench-{r['backend']}.npy")
        frame = f"{r['frame_s'] * 1e3:.1f} ms" if "frame_s" in r else ""
        print(f"| {r['backend']} | {r['build_s'] * 1e3:.0f} ms | {r['cast_s'] * 1e3:.1f} ms | "
              f"{r['rays'] / r['cast_s'] / 1e6:.2f} | {bvh / r['cast_s']:.1f}x | "
              f"{np.mean(tri == ref):.5f} | {frame} |")
    extra = [r for r in rows if "kernel_compile_s" in r]
    for r in extra:
        print(f"\nwarp: kernel compile on first use {r['kernel_compile_s']:.1f} s (cached after)")
    print("\nwheels in build/wheels:")
    for name, size in wheel_sizes().items():
        print(f"  {name}  {size / 2 ** 20:.1f} MiB")


if __name__ == "__main__":
    main()
