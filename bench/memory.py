"""Peak memory of building each backend and casting one Pandar64 frame, one subprocess
per case: the report's section *Peak memory*."""

import json
import subprocess
import sys
from pathlib import Path

from bench.timing import log

ROOT = Path(__file__).resolve().parents[1]

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


def measure(sizes):
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


def section(mem):
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
