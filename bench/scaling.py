"""A frame's cast against scene size (triangles) and against rays per call, with every
backend and baseline: the report's section *Scaling* and its chart."""

import gc

import numpy as np

from bench.backends import Backends
from bench.timing import log, mrays, ms

SCALING_TRIANGLES = [10_000, 100_000, 300_000, 1_000_000, 2_000_000, 4_000_000]
SCALING_RAYS = [10_000, 30_000, 100_000, 300_000, 1_000_000]


def triangles(pose, preset, quick):
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


def rays(geometry, pose, preset, quick):
    rng = np.random.default_rng(0)
    base = preset.pattern().directions
    be = Backends(geometry, pose[:3, 3], preset.range.max_m, prepared=False)
    out = []
    for n in (SCALING_RAYS[:4] if quick else SCALING_RAYS):
        dirs = np.ascontiguousarray(base[rng.integers(0, len(base), n)])
        log(f"bench: scaling: {n:,} rays")
        out.append({"rays": n, "cast_s": be.cast_times(dirs, preset.range.max_m, repeat=3)})
    return out


def chart(tri_rows, ray_rows, path):
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


def section(charts, tri_rows, ray_rows):
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
