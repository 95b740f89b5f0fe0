"""A placement study's report: tables, JSON and charts (``rls study`` writes them).

  candidates.csv   one row per candidate: pose, points in the region, InfraD, InfraNUC
                   (and with traffic: visibility shares, mean points, ranks)
  placements.csv   every evaluated k-set: members, InfraD, InfraNUC, Pareto flag, best
                   (and with traffic: visibility of the set)
  study.json       settings, timing, candidates, per-k Pareto front and best set, the
                   best sets' density maps; with traffic the best set by visibility
  pareto.png       InfraD against InfraNUC, one panel per k: every set evaluated, the
                   Pareto front joined, the best set starred and named
  density_k<K>.png density map (points / m² per cell, world x/y in metres) of the best
                   set of each k, sensors and region outline marked, cells outside the
                   region grey, cells with no return white; every k on one colour scale
                   (0 to the densest cell of any)
  visibility.png   with traffic: InfraD, InfraNUC and visibility of each candidate
                   and of the best sets, side by side
  ap_vs_<metric>.png  with --evaluate: the detector's AP against InfraD, InfraNUC and
                   each visibility share, one point per placement scored, the fit and
                   its coefficients (``evaluate/correlation.py``); the AP of each
                   candidate and scored set is the ``ap_vehicle_bev50`` column of the
                   tables, the whole evaluation in study.json's ``evaluation``

Chart titles name the scene by its file (``StudyResult.title``). Charts need matplotlib (Agg); without it the density maps are written with RLS's own
PNG writer (no axes or scale, each map scaled to its own maximum) and the other charts
are skipped (a notice says so). The density charts are drawn by ``core/metrics/charts.py``.
"""

import csv
import io
import json
import math
import os

from ..metrics import charts
from ..metrics.visibility import RANK_BY


def _fmt(v, nd=6):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return round(v, nd) if isinstance(v, float) else v


def _csv(rows, fields):
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({f: _fmt(r.get(f)) for f in fields})
    return buf.getvalue().encode("utf-8")


def placement_rows(result):
    names = [c.name for c in result.candidates]
    rows = []
    for k, s in sorted(result.searches.items()):
        front = {p.members for p in s.front}
        for p in sorted(s.evaluated, key=lambda p: (-p.infra_d, p.infra_nuc)):
            row = {"k": k, "sensors": " + ".join(names[i] for i in p.members),
                   "members": " ".join(str(i) for i in p.members),
                   "points_in_lob": p.n_points, "infra_d": p.infra_d,
                   "infra_nuc": p.infra_nuc, "pareto": int(p.members in front),
                   "best": int(p.members == s.best.members), "method": s.method}
            if result.visibility is not None:
                row.update(result.visibility.sets[k][p.members].to_dict())
            if result.evaluation is not None:
                ev = result.evaluation
                scored = len(p.members) == 1 or tuple(p.members) in ev.sets
                row[AP_FIELD] = ev.ap_of(p.members) if scored else None
            rows.append(row)
    return rows


def report_dict(result):
    names = [c.name for c in result.candidates]
    cfg = result.config
    out = {
        "scene": result.scene, "scene_file": result.scene_file, "frame": result.frame,
        "device": result.device,
        "region": {"polygon_xy": result.polygon.tolist(), "area_m2": result.layout.area_m2,
                   "labels": cfg.labels, "disks": cfg.disks, "radius_m": cfg.radius,
                   "disk_seed": cfg.disk_seed, "disk_placement": cfg.disk_placement},
        "settings": {"k": list(cfg.k), "pitch_deg": list(cfg.pitches), "yaw_deg": list(cfg.yaws),
                     "yaw_mode": cfg.yaw_mode, "roll_deg": cfg.roll, "scan_seed": cfg.scan_seed,
                     "noise": cfg.noise, "dropout": cfg.dropout,
                     "one_sensor_per_mount": cfg.one_per_mount,
                     "traffic_removed": not cfg.keep_traffic,
                     "rotation_hz": getattr(cfg, "rotation_hz", None),
                     "lidar_mode": getattr(cfg, "lidar_mode", None)},
        "hidden_traffic": result.hidden_traffic,
        "notices": list(result.notices),  # what a reader should know (printed too)
        "backend": result.backend, "structure_builds": result.structure_builds,
        "timing_s": {k: round(v, 4) for k, v in result.timing.items()},
        "candidates": candidate_rows(result),
        "placements": {},
    }
    vis = result.visibility
    if vis is not None:
        out["visibility"] = {
            "frames": vis.frames, "vehicle_frames": len(vis.vehicle_frames),
            "vehicles": len({key for _, key in vis.vehicle_frames}),
            "labels": list(cfg.visibility_labels), "thresholds": list(cfg.visibility_thresholds),
            "ranked_by": f"share of vehicle-frames with >= {RANK_BY} points",
            "best": {str(k): dict(v.to_dict(), members=list(v.members),
                                  sensors=[names[i] for i in v.members])
                     for k, v in sorted(vis.best.items())},
            "rank_disagreements": [
                {"candidate": names[i], "rank_infra_d": int(vis.rank_infra_d[i]),
                 "rank_visibility": int(vis.rank_visibility[i])}
                for i in range(len(names)) if vis.rank_infra_d[i] != vis.rank_visibility[i]],
        }
    if result.evaluation is not None:
        out["evaluation"] = result.evaluation.to_dict(names)
    for k, s in sorted(result.searches.items()):
        out["placements"][str(k)] = {
            "method": s.method, "sets": s.sets_total, "evaluated": len(s.evaluated),
            "pareto_front": [p.to_dict(names) for p in s.front],
            "best": s.best.to_dict(names),
            "best_density": result.density(s.best.members).to_dict(),
        }
    return out


REPORT_FILES = ("candidates.csv", "placements.csv", "study.json", "pareto.png")
AP_FIELD = "ap_vehicle_bev50"  # with --evaluate: vehicle AP_R40 at BEV IoU 0.5
VISIBILITY_FIELDS = ("share_5", "share_20", "share_50", "mean_points", "never_seen")
VISIBILITY_ROWS = 30  # candidates listed in visibility.png (the best, and best-set members)


def candidate_rows(result):
    """One dict per candidate; with traffic its visibility and its ranks by InfraD and
    by visibility (1 = best)."""
    rows = [c.row() for c in result.candidates]
    vis = result.visibility
    if vis is not None:
        for i, r in enumerate(rows):
            r.update(vis.candidates[i].to_dict(), rank_infra_d=int(vis.rank_infra_d[i]),
                     rank_visibility=int(vis.rank_visibility[i]))
    if result.evaluation is not None:
        for r, (ap, _) in zip(rows, result.evaluation.candidates):
            r[AP_FIELD] = ap
    return rows


def report_clash(out_dir, ks):
    """The first file of a report of ``ks`` that already exists in ``out_dir``, or None."""
    names = list(REPORT_FILES) + [f"density_k{k}.png" for k in ks]
    return next((os.path.join(out_dir, f) for f in names
                 if os.path.exists(os.path.join(out_dir, f))), None)


def write_report(result, out_dir, overwrite=False, notices=None, charts=None):
    """Write the report files into ``out_dir``; returns a summary dict. Notices (e.g.
    matplotlib missing) are appended to ``notices`` when given. ``charts``: the
    (files, notice) of ``charts_png(result)`` when the caller drew them already."""
    from ..output.io.atomic import atomic_write_files

    rows = candidate_rows(result)
    files = {}
    files["candidates.csv"] = _csv(rows, list(rows[0].keys()))
    vis_fields = list(VISIBILITY_FIELDS) if result.visibility is not None else []
    ap_fields = [AP_FIELD] if result.evaluation is not None else []
    files["placements.csv"] = _csv(placement_rows(result),
                                   ["k", "sensors", "members", "points_in_lob", "infra_d",
                                    "infra_nuc", "pareto", "best", "method"] + vis_fields
                                   + ap_fields)
    report = report_dict(result)
    drawn, notice = charts if charts is not None else charts_png(result)
    files.update(drawn)
    report["charts"] = sorted(drawn)
    if notice:
        report["notice"] = notice
        if notices is not None:
            notices.append(notice)
    files["study.json"] = (json.dumps(report, indent=2, allow_nan=False) + "\n").encode("utf-8")
    # the report is one set: a failure leaves none of its files, not a part
    written = [os.path.abspath(p) for p in atomic_write_files(
        {os.path.join(out_dir, name): files[name] for name in sorted(files)},
        overwrite=overwrite)]
    names = [c.name for c in result.candidates]
    return {
        "scene": result.scene, "device": result.device["id"],
        "candidates": len(result.candidates),
        "seconds": round(result.timing["total_s"], 3),
        "per_candidate_s": round(result.timing["per_candidate_s"], 4),
        "structure_builds": result.structure_builds,
        "best": {str(k): {"sensors": [names[i] for i in s.best.members],
                          "infra_d": round(s.best.infra_d, 4),
                          "infra_nuc": round(s.best.infra_nuc, 4), "method": s.method}
                 for k, s in sorted(result.searches.items())},
        **({"best_by_visibility": {
            str(k): dict(v.to_dict(), sensors=[names[i] for i in v.members])
            for k, v in sorted(result.visibility.best.items())}}
           if result.visibility is not None else {}),
        **({"best_by_ap": report["evaluation"]["best_by_ap"]}
           if result.evaluation is not None else {}),
        "report": os.path.abspath(os.path.join(out_dir, "study.json")),
        "files": written,
    }


def density_maps(result):
    """{k: DensityMap of the best set of k}, and the (vmin, vmax) colour scale all of
    them are drawn with (0 to the densest cell of any), so colours compare across k."""
    maps = {k: result.density(s.best.members) for k, s in sorted(result.searches.items())}
    return maps, charts.density_scale(maps.values())


def charts_png(result):
    """{file name: PNG bytes}, and a notice when matplotlib is missing."""
    maps, scale = density_maps(result)
    if charts.pyplot() is None:
        out = {f"density_k{k}.png": dm.to_png() for k, dm in maps.items()}
        return out, (f"{charts.MATPLOTLIB_MISSING}: pareto.png skipped, density maps drawn "
                     "without axes or scale, each scaled to its own maximum (pip install "
                     "matplotlib)")
    out = {"pareto.png": _pareto_png(result),
           **{f"density_k{k}.png": charts.figure_png(density_figure(result, k, maps[k], scale))
              for k in maps}}
    if result.visibility is not None:
        out["visibility.png"] = _visibility_png(result)
    if result.evaluation is not None:
        out.update(_ap_charts(result))
    return out, None


def _ap_charts(result):
    """``ap_vs_<metric>.png``: AP against each metric, one point per placement scored,
    coloured by k (``ap_charts.py``)."""
    from .ap_charts import METRICS, ap_chart_png

    ev = result.evaluation
    out = {}
    for name in METRICS:
        if name not in ev.correlation:
            continue
        png = ap_chart_png(ev.placements, name, ev.correlation[name],
                           {k: c[name] for k, c in ev.by_k.items()}, result.title)
        if png is not None:
            out[f"ap_vs_{name}.png"] = png
    return out


def _visibility_png(result):
    """Per candidate and per best set (by InfraD/NUC and by visibility): InfraD,
    InfraNUC and the share of vehicle-frames seen by >= 20 points, in three panels with
    one row each, so where the traffic-free metrics and visibility disagree shows."""
    import matplotlib.pyplot as plt
    import numpy as np

    vis, names = result.visibility, [c.name for c in result.candidates]
    shown = _candidates_shown(result)
    rows = [(result.candidates[i].name, result.candidates[i].infra_d,
             result.candidates[i].infra_nuc, vis.candidates[i].score) for i in shown]
    counts = result.counts
    for k, s in sorted(result.searches.items()):
        if k == 1:
            continue
        for tag, members in (("best InfraD/NUC", s.best.members), ("best visibility",
                                                                    vis.best[k].members)):
            p = counts.evaluate([members])[0]
            v = vis.sets[k].get(tuple(members)) or vis.counts.evaluate([members])[0]
            rows.append((f"k={k} {tag}: " + " + ".join(names[i] for i in members),
                         p.infra_d, p.infra_nuc, v.score))
    labels = [r[0] for r in rows]
    y = np.arange(len(rows))
    fig, axes = plt.subplots(1, 3, figsize=(13, 0.42 * len(rows) + 1.8), sharey=True)
    panels = (("InfraD (points / m², higher is denser)", 1, "tab:blue"),
              ("InfraNUC (lower is more uniform)", 2, "tab:orange"),
              (f"vehicle-frames seen by >= {RANK_BY} points (share)", 3, "tab:green"))
    for ax, (title, col, colour) in zip(axes, panels):
        vals = np.array([r[col] if r[col] is not None else np.nan for r in rows], float)
        ax.barh(y, np.nan_to_num(vals), color=colour)
        ax.set_xlabel(title)
        ax.grid(axis="x", alpha=0.3)
        for yi, v in zip(y, vals):
            ax.text(v if np.isfinite(v) else 0, yi, f" {v:.3g}", va="center", fontsize=7)
    axes[0].set_yticks(y)
    axes[0].set_yticklabels(labels, fontsize=7)
    axes[0].invert_yaxis()
    more = len(result.candidates) - len(shown)
    fig.suptitle(f"{result.title}: traffic-free metrics and visibility of the traffic over "
                 f"{len(vis.frames)} frames ({len(vis.vehicle_frames)} vehicle-frames)"
                 + (f"\n{len(shown)} of {len(result.candidates)} candidates: the best by "
                    "visibility and the best sets' members (all in candidates.csv)" if more else ""))
    fig.tight_layout()
    return _fig_bytes(fig)


def _candidates_shown(result, limit=VISIBILITY_ROWS):
    """Indices of the candidates the visibility chart lists, in the study's order: all
    of them up to ``limit``, else the ``limit`` best by visibility and every member of
    a best set (a chart of hundreds of rows is neither readable nor quick to draw)."""
    n = len(result.candidates)
    if n <= limit:
        return list(range(n))
    vis = result.visibility
    keep = set(sorted(range(n), key=lambda i: (-vis.candidates[i].score, i))[:limit])
    for k, s in result.searches.items():
        keep.update(s.best.members)
        if k in vis.best:
            keep.update(vis.best[k].members)
    return sorted(keep)


def _fig_bytes(fig):
    return charts.figure_png(fig)


PARETO_COLUMNS = 3  # panels per row of pareto.png


def _pareto_png(result):
    """InfraD against InfraNUC, one panel per k (each on its own axes, so the many
    sets of a large k do not bury the few of k = 1): every set evaluated, the Pareto
    front joined, the best set starred and named."""
    import textwrap

    import matplotlib.pyplot as plt
    import numpy as np

    searches = sorted(result.searches.items())
    names = [c.name for c in result.candidates]
    cols = min(PARETO_COLUMNS, len(searches))
    rows = -(-len(searches) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 4.1 * rows + 0.7),
                             squeeze=False, layout="constrained")
    for j, (ax, (k, s)) in enumerate(zip(axes.flat, searches)):
        colour = plt.get_cmap("tab10")(j % 10)
        d = np.array([p.infra_d for p in s.evaluated], float)
        u = np.array([p.infra_nuc for p in s.evaluated], float)
        how = (f"all {s.sets_total:,}" if len(s.evaluated) >= s.sets_total
               else f"{len(s.evaluated):,} of {s.sets_total:,}")
        ax.scatter(d, u, s=16, alpha=0.5, color="0.45", linewidths=0,
                   label=f"sets evaluated ({how}, {s.method})")
        ax.plot([p.infra_d for p in s.front], [p.infra_nuc for p in s.front], "-o",
                color=colour, markersize=6, markerfacecolor="none",
                label=f"Pareto front ({len(s.front)})")
        ax.scatter([s.best.infra_d], [s.best.infra_nuc], marker="*", s=220, color=colour,
                   edgecolor="black", zorder=5, label="best (balanced score)")
        best = " + ".join(names[i] for i in s.best.members)
        ax.set_title("\n".join([f"k = {k}"] + textwrap.wrap(f"best: {best}", 48)), fontsize=9)
        ax.set_xlabel("InfraD (points / m², higher is denser)")
        ax.set_ylabel("InfraNUC (lower is more uniform)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in list(axes.flat)[len(searches):]:
        ax.set_visible(False)
    fig.suptitle(f"{result.title}: {result.device['name']}, {len(result.candidates)} "
                 "candidates: InfraD against InfraNUC, one panel per k", fontsize=10)
    return _fig_bytes(fig)


def density_figure(result, k, dm, scale):
    """The density chart of the best set of k (``dm``), on the study's shared ``scale``."""
    search = result.searches[k]
    b = search.best
    names = [c.name for c in result.candidates]
    sensors = [(c.name, c.position[0], c.position[1], c.yaw_deg if c.pitch_deg else None)
               for c in (result.candidates[i] for i in b.members)]
    ks = ", ".join(str(j) for j in sorted(result.searches))
    note = (f"one scale for k = {ks}: {scale[0]:g} to {scale[1]:.3g}" if len(result.searches) > 1
            else f"scale {scale[0]:g} to {scale[1]:.3g}")
    title = charts.density_title(
        f"{result.title}, {result.device['name']}: best set of k = {k}: "
        + " + ".join(names[i] for i in b.members),
        b.infra_d, b.infra_nuc, f"{b.n_points:,} points in the region, {search.method} search")
    return charts.density_figure(dm, title, polygon=result.polygon, sensors=sensors,
                                 scale=scale, scale_note=note)
