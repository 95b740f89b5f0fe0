"""The report and charts of ``make bench`` from its raw numbers (``bench/run.py``
measures; ``python bench/run.py --from-json`` rewrites these from a saved run):
``docs/benchmarks.md`` a section per function, the scaling and tessellation charts."""

import importlib
from pathlib import Path

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
    # each module's own section, in the report's order (the key is the module's name)
    for name in ("drive_costs", "effect_costs", "study_costs", "evaluate_costs", "long_runs",
                 "traffic_costs", "live_costs", "scale_out"):
        if costs.get(name):
            L.extend(importlib.import_module(f"bench.{name}").section(costs[name]))
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
