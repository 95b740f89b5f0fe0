"""What a placement study costs per candidate (issue 18, "Studies count, they do not
build clouds"), on a synthetic junction without Blender (``BenchStudyScene``: a 60 m
road square, a sidewalk ring out to 100 m, 40 buildings, a parked van that the study
leaves out as traffic, and N mounts 20-28 m from the centre at 4-9 m).

- ``study_memory_per_1000``: the memory ``run_study`` keeps per candidate (what is
  still allocated while its result is held) and its peak, under ``tracemalloc``, as the
  slope between two candidate counts (so the fixed costs, the prepared scene and the
  pattern, drop out), in bytes per candidate and MB per 1,000 candidates. Target: at
  most 50 KB kept per candidate.
- ``study_seconds_per_candidate``: a study's scan time per candidate against the
  candidate's cast alone (the pattern's rays from its pose into the prepared triangles
  with the bare backend: no re-check of misses, no refinement, no points), as
  (seconds per candidate, cast alone in seconds, ratio). Target: ratio <= 1.5.
- ``study_cost_parts``: where a candidate's time goes: its frame (``scan_frame`` with
  the study's fields), the selection of its points in the region, their counts in the
  disks (``DiskLayout.counts``), and once per study the disks' grid (``DiskCounter``);
  and the share of the pattern's rays the candidates cast (those outside the region
  cast only the rays toward it, ``StudyScanner.rays_toward_region``).

Run alone: ``python bench/study_costs.py [--quick]`` (prints JSON with the load average).
"""

import gc
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import standalone  # noqa: E402 - after the path above

REGION = np.array([(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)])


class BenchStudyScene:
    """A ``core.scene.source.StudyScene`` of numpy geometry with ``mounts`` candidate mounts."""

    name = "bench junction"

    def __init__(self, mounts=200, seed=5):
        from bench.scene import MAT, box, grid
        from rls_addon.core.labels import NAME_TO_ID

        rng = np.random.default_rng(seed)
        self.frame = 1
        parts = [("Road", "road", "asphalt", grid((-30, -30, 0), (60, 0, 0), (0, 60, 0), 30, 30))]
        for k, (p0, u, v) in enumerate((((-100, -100, 0), (200, 0, 0), (0, 70, 0)),
                                        ((-100, 30, 0), (200, 0, 0), (0, 70, 0)),
                                        ((-100, -30, 0), (70, 0, 0), (0, 60, 0)),
                                        ((30, -30, 0), (70, 0, 0), (0, 60, 0)))):
            parts.append((f"Sidewalk {k}", "sidewalk", "concrete", grid(p0, u, v, 20, 20)))
        for i in range(40):
            r, a = rng.uniform(34, 80), rng.uniform(0, 2 * np.pi)
            c = np.array([r * np.cos(a), r * np.sin(a)])
            half = rng.uniform(2.0, 6.0, 2)
            parts.append((f"Building {i}", "building", "facade",
                          box((*(c - half), 0.0), (*(c + half), rng.uniform(4.0, 20.0)), 2)))
        parts.append(("Van", "vehicle", "paint", box((2, -3, 0), (7, -1, 2.5))))
        self.parts = [(n, NAME_TO_ID[lab], MAT[mat], vt) for n, lab, mat, vt in parts]
        r, a = rng.uniform(20.0, 28.0, mounts), rng.uniform(0, 2 * np.pi, mounts)
        z = rng.uniform(4.0, 9.0, mounts)
        self._mounts = [(f"M{i:04d}", (float(r[i] * np.cos(a[i])), float(r[i] * np.sin(a[i])),
                                       float(z[i]))) for i in range(mounts)]

    def current_frame(self):
        return self.frame

    def set_frame(self, frame):
        self.frame = int(frame)

    def region(self, name):
        return REGION.copy()

    def mounts(self, names):
        return [m for m in self._mounts if not names or m[0] in names]

    def static_geometry(self, hidden_labels):
        from bench.scene import MATERIALS
        from rls_addon.core.scene.geometry import ObjectInfo, SceneGeometry

        keep = [p for p in self.parts if p[1] not in hidden_labels]
        verts, tris, objs, mats, objects, off = [], [], [], [], [], 0
        for k, (name, label, mat, (v, t)) in enumerate(keep):
            objects.append(ObjectInfo(name, label, k + 1))
            verts.append(v)
            tris.append(t + off)
            objs.append(np.full(len(t), k))
            mats.append(np.full(len(t), mat))
            off += len(v)
        geometry = SceneGeometry(np.concatenate(verts), np.concatenate(tris),
                                 np.concatenate(objs), np.concatenate(mats), objects,
                                 list(MATERIALS))
        return geometry, sorted(p[0] for p in self.parts if p[1] in hidden_labels)


def _config(device, backend, k=(1, 2), exhaustive_limit=None):
    from rls_addon.core.study.config import StudyConfig

    extra = {} if exhaustive_limit is None else {"exhaustive_limit": exhaustive_limit}
    return StudyConfig(device=device, k=tuple(k), backend=backend, **extra)


def _run(candidates, device, backend, exhaustive_limit=None, scan_all=None):
    from rls_addon.core.study.loop import run_study

    return run_study(BenchStudyScene(candidates), _config(device, backend,
                                                          exhaustive_limit=exhaustive_limit),
                     scan_all=scan_all)


def study_memory_per_1000(candidates=(100, 400), device="generic_uniform32", backend="auto"):
    """Memory a study keeps per candidate (still allocated while its result is held),
    its peak while the candidates are scanned and its peak over the whole study: each
    the slope between the two candidate counts under ``tracemalloc``, in bytes per
    candidate and MB per 1,000 candidates, with each run's raw numbers.

    The search is greedy+swap in both runs (``exhaustive_limit=0``): the exhaustive
    search's batches cost the same however many candidates there are, and would hide
    the slope."""
    small, large = sorted(candidates)
    _run(3, device, backend)  # imports, the preset's pattern, the compiled loop
    runs = {}
    started = tracemalloc.is_tracing()
    if not started:
        tracemalloc.start()
    try:
        for n in (small, large):
            scanned = {}

            def scan_all(scanner, cands, on_scan, scanned=scanned):
                for c in cands:
                    on_scan(scanner.scan(c))
                scanned["peak"] = tracemalloc.get_traced_memory()[1]

            gc.collect()
            base = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            result = _run(n, device, backend, exhaustive_limit=0, scan_all=scan_all)
            gc.collect()
            now, peak = tracemalloc.get_traced_memory()
            runs[n] = {"kept_bytes": now - base, "scan_peak_bytes": scanned["peak"] - base,
                       "peak_bytes": peak - base,
                       "per_candidate_s": result.timing["per_candidate_s"]}
            del result
    finally:
        if not started:
            tracemalloc.stop()
    span = large - small

    def slope(key):
        return (runs[large][key] - runs[small][key]) / span

    kept, scan_peak, peak = slope("kept_bytes"), slope("scan_peak_bytes"), slope("peak_bytes")
    return {"candidates": [small, large], "device": device,
            "kept_bytes_per_candidate": round(kept),
            "scan_peak_bytes_per_candidate": round(scan_peak),
            "peak_bytes_per_candidate": round(peak),
            "kept_mb_per_1000": round(kept * 1000 / 1e6, 2),
            "scan_peak_mb_per_1000": round(scan_peak * 1000 / 1e6, 2),
            "peak_mb_per_1000": round(peak * 1000 / 1e6, 2), "runs": runs}


def _cast_alone(candidates, device, backend, repeat):
    """Mean over ``candidates`` of the best of ``repeat`` bare casts of each one's rays."""
    from rls_addon.core.scan.device_values import device_values
    from rls_addon.core.study.scanner import StudyScanner, study_inputs

    scene = BenchStudyScene(candidates)
    cfg = _config(device, backend)
    inputs = study_inputs(scene, cfg)
    scanner = StudyScanner(scene, cfg, inputs.preset, inputs.polygon, inputs.layout,
                           inputs.candidates)
    prepared = scanner.prepared
    raw = scanner.backend_cls(prepared.vertices, prepared.triangles)
    pattern = inputs.preset.pattern(scanner.frame)
    rmax = device_values(inputs.preset, scanner.settings).max_range_m
    times = []
    for c in inputs.candidates:
        dirs = np.ascontiguousarray(pattern.directions @ c.pose[:3, :3].T)
        origin = (c.pose[:3, 3] - prepared.centre).reshape(1, 3)
        best = float("inf")
        for _ in range(repeat):
            t = time.perf_counter()
            raw.cast(origin, dirs, rmax)
            best = min(best, time.perf_counter() - t)
        times.append(best)
    return float(np.mean(times))


def study_seconds_per_candidate(candidates=40, device="generic_uniform32", backend="auto",
                                repeat=3):
    """(study seconds per candidate, the candidate's cast alone in seconds, ratio): the
    best of ``repeat`` studies' scan time per candidate, against the best of ``repeat``
    rounds of the mean over the candidates of their bare casts (each the better of
    two). Taken in turns, so a burst of load on a shared machine hits both alike."""
    _run(3, device, backend)  # warm up
    study = cast = float("inf")
    for _ in range(repeat):
        study = min(study, _run(candidates, device, backend).timing["per_candidate_s"])
        cast = min(cast, _cast_alone(candidates, device, backend, 2))
    return study, cast, study / cast


def study_cost_parts(candidates=40, device="generic_uniform32", backend="auto", repeat=3):
    """Where a candidate's time goes, in seconds per candidate (best of ``repeat``):
    ``frame_and_select_s`` (``scan_frame`` with the study's fields, then the points in
    the region with a counted label), ``select_s`` (that selection alone, from the
    frame's points), ``disks_s`` (``DiskLayout.counts`` of those) and ``scan_s`` (all
    of ``StudyScanner.scan``); and once per study, ``disk_grid_s`` (the layout's
    ``DiskCounter``, built while the scanner prepares the scene)."""
    from rls_addon.core.metrics.disk_counter import DiskCounter
    from rls_addon.core.study.scanner import StudyScanner, study_inputs

    scene = BenchStudyScene(candidates)
    cfg = _config(device, backend)
    inputs = study_inputs(scene, cfg)
    scanner = StudyScanner(scene, cfg, inputs.preset, inputs.polygon, inputs.layout,
                           inputs.candidates)
    cands, layout = inputs.candidates, inputs.layout
    kept = [scanner.kept_xy(c) for c in cands]
    clouds = [scanner._static(c)[1].points for c in cands]

    def each(fn):
        best = float("inf")
        for _ in range(repeat):
            t = time.perf_counter()
            for i, c in enumerate(cands):
                fn(i, c)
            best = min(best, (time.perf_counter() - t) / len(cands))
        return best

    n_rays = len(scanner.preset.pattern(scanner.frame))
    toward = [scanner.rays_toward_region(c) for c in cands]
    grid = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        DiskCounter(layout.centres, layout.radius_m)
        grid = min(grid, time.perf_counter() - t)
    return {"frame_and_select_s": each(lambda i, c: scanner.kept_xy(c)),
            "select_s": each(lambda i, c: layout.select([clouds[i]], scanner.label_ids)),
            "disks_s": each(lambda i, c: layout.counts(kept[i])),
            "scan_s": each(lambda i, c: scanner.scan(c)),
            "disk_grid_s": grid,
            # candidates outside the region cast only the rays toward it
            "outside": sum(t is not None for t in toward), "candidates": len(cands),
            "rays_cast_share": float(np.mean([1.0 if t is None else len(t) / n_rays
                                              for t in toward])),
            "points_in_region": int(np.mean([len(x) for x in kept])),
            "disks": len(layout.centres)}


def measure(quick=False):
    """Memory, seconds per candidate against its cast, and where the time goes."""
    load = os.getloadavg()
    mem = study_memory_per_1000((50, 150) if quick else (100, 400))
    s, c, ratio = study_seconds_per_candidate(20 if quick else 40, repeat=2 if quick else 3)
    parts = study_cost_parts(20 if quick else 40, repeat=2 if quick else 3)
    return {"load_average_before": [round(v, 2) for v in load],
            "memory": mem,
            "seconds_per_candidate": {"study_s": round(s, 5), "cast_alone_s": round(c, 5),
                                      "ratio": round(ratio, 3)},
            "parts_s_per_candidate": {k: round(v, 5) if isinstance(v, float) else v
                                      for k, v in parts.items()},
            "targets": {"kept_bytes_per_candidate <= 50000":
                        mem["kept_bytes_per_candidate"] <= 50_000, "ratio <= 1.5": ratio <= 1.5},
            "load_average_after": [round(v, 2) for v in os.getloadavg()]}


def section(res):
    """Markdown of ``measure``'s result for docs/benchmarks.md."""
    mem, sec, parts = res["memory"], res["seconds_per_candidate"], res["parts_s_per_candidate"]
    return ["## A study candidate against its cast (issue 18)\n",
            f"`run_study` on a synthetic junction without Blender (`bench/study_costs.py`: "
            f"road, sidewalks, 40 buildings, {mem['device']}). A candidate keeps only its "
            f"counts per disk; the cast alone is the bare backend on the candidate's rays.\n",
            "| measure | value | target |", "|---|---|---|",
            f"| seconds per candidate | {sec['study_s'] * 1e3:.1f} ms, "
            f"**{sec['ratio']:.2f}x** its cast alone ({sec['cast_alone_s'] * 1e3:.1f} ms) | "
            f"<= 1.5x |",
            f"| of which: frame / selection / disk counts | "
            f"{(parts['frame_and_select_s'] - parts['select_s']) * 1e3:.1f} ms / "
            f"{parts['select_s'] * 1e3:.1f} ms / {parts['disks_s'] * 1e3:.1f} ms "
            f"({parts['points_in_region']:,} points in the region, {parts['disks']} disks; "
            f"their grid, once per study: {parts['disk_grid_s'] * 1e3:.0f} ms) | |",
            f"| rays cast, share of the pattern's | {parts['rays_cast_share']:.0%} on average "
            f"({parts['outside']} of {parts['candidates']} candidates stand outside the "
            f"region and cast only the rays toward it; the cast alone above is all the "
            f"pattern's rays) | |",
            f"| memory kept per candidate | **{mem['kept_bytes_per_candidate'] / 1e3:.1f} KB** "
            f"({mem['kept_mb_per_1000']} MB per 1,000) | <= 50 KB |",
            f"| peak while scanning, per 1,000 candidates | {mem['scan_peak_mb_per_1000']} MB "
            f"(whole study: {mem['peak_mb_per_1000']} MB) | |",
            f"\nLoad average before / after: {res['load_average_before'][0]:.2f} / "
            f"{res['load_average_after'][0]:.2f}.\n"]


def main(argv=None):
    return standalone.main(__doc__, measure, section, argv)


if __name__ == "__main__":
    main()
