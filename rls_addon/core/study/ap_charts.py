"""``ap_vs_<metric>.png``: a study's detection AP against a cheap metric, one point per
placement scored, coloured by the number of sensors k, each point named, AP on 0-1 as
in the tables, the correlations pooled and within each k in the legend (a pooled
correlation mixes "more sensors" with "better placement"). The title names the scene
file."""

import numpy as np

from ..metrics import charts

METRICS = {"infra_d": "InfraD (points/m²)", "infra_nuc": "InfraNUC",
           "share_5": "Share of vehicle-frames seen by ≥ 5 points",
           "share_20": "Share of vehicle-frames seen by ≥ 20 points",
           "share_50": "Share of vehicle-frames seen by ≥ 50 points"}
AP_LABEL = "Vehicle AP (R40, BEV IoU 0.5)"
K_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")


def short_name(sensors):
    """A placement's label: its candidates' names, 'pitch 15 yaw +0' as 'p15'."""
    out = []
    for name in sensors:
        name = name.replace(" pitch ", " p").replace(" yaw +0", "")
        out.append(name.replace(" yaw ", " y"))
    return " + ".join(out)


def _uncrowded(x, y, ok, near=(0.06, 0.025)):
    """Indices of the points to name: by falling AP (the best placements first), each
    unless a point already named lies within ``near`` (shares of the x and y spans)."""
    if not ok.any():
        return []
    span_x = max(np.ptp(x[ok]), 1e-12)
    named = []
    for i in sorted(np.flatnonzero(ok), key=lambda i: (-y[i], x[i])):
        if all(abs(x[i] - x[j]) > near[0] * span_x or abs(y[i] - y[j]) > near[1]
               for j in named):
            named.append(int(i))
    return named


def _coefficients(res):
    if res is None or res.get("pearson") is None:
        return "no correlation" + (f" ({res['reason']})" if res and res.get("reason") else "")
    p, s = res["pearson"], res["spearman"]

    def ci(c):
        return "" if c["ci"] is None else f" [{c['ci'][0]:+.2f}, {c['ci'][1]:+.2f}]"
    return f"r = {p['r']:+.2f}{ci(p)}, ρ = {s['r']:+.2f}{ci(s)}"


def ap_chart_png(rows, metric, pooled, by_k, scene):
    """PNG bytes of ``ap_chart_figure``; None without matplotlib."""
    fig = ap_chart_figure(rows, metric, pooled, by_k, scene)
    return None if fig is None else charts.figure_png(fig)


def ap_chart_figure(rows, metric, pooled, by_k, scene):
    """The figure of AP against ``metric`` (a key of ``METRICS``) over placement ``rows``
    (``StudyEvaluation.placements``: members, sensors, ap, metrics), with the pooled and
    per-k (``by_k``: {k: record}) ``correlation`` records; None without matplotlib."""
    plt = charts.pyplot()
    if plt is None:
        return None
    x = np.array([np.nan if r.get(metric) is None else r[metric] for r in rows], np.float64)
    y = np.array([np.nan if r["ap"] is None else r["ap"] for r in rows], np.float64)
    k = np.array([len(r["members"]) for r in rows])
    fig, ax = plt.subplots(figsize=(8.0, 5.6), dpi=charts.DPI)
    ok = np.isfinite(x) & np.isfinite(y)
    for n, kk in enumerate(sorted(set(k.tolist()))):
        sel = ok & (k == kk)
        colour = K_COLOURS[n % len(K_COLOURS)]
        label = (f"k = {kk} ({int(sel.sum())} placements): "
                 f"{_coefficients(by_k.get(kk) or by_k.get(str(kk)))}")
        ax.scatter(x[sel], y[sel], s=26, color=colour, zorder=3, label=label)
        if sel.sum() >= 2 and np.ptp(x[sel]) > 0:
            a, b = np.polyfit(x[sel], y[sel], 1)
            xs = np.linspace(x[sel].min(), x[sel].max(), 20)
            ax.plot(xs, a * xs + b, color=colour, lw=1.0, alpha=0.7)
    named = _uncrowded(x, y, ok)
    for i in named:
        ax.annotate(short_name(rows[i]["sensors"]), (x[i], y[i]), fontsize=5.5,
                    xytext=(3, 2), textcoords="offset points", color="#333333")
    ax.plot([], [], " ", label=f"all {int(ok.sum())} placements: {_coefficients(pooled)}")
    if len(named) < ok.sum():
        ax.plot([], [], " ", label=f"({int(ok.sum()) - len(named)} names left out where "
                                   "points crowd: study.json lists every placement)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(METRICS[metric])
    ax.set_ylabel(AP_LABEL)
    ax.set_title(f"{scene}: vehicle AP against {METRICS[metric]}\n"
                 "Pearson r and Spearman ρ with 95% bootstrap intervals", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=6.5)
    fig.tight_layout()
    return fig
