"""How well a cheap placement metric predicts detection quality: across placements,
the Pearson and Spearman correlation of AP with the metric (InfraD, InfraNUC, a
visibility share), each with a bootstrap 95% interval, and a chart per metric.

The coefficients are scipy's (``scipy.stats.pearsonr``, ``spearmanr``). The interval is
the percentile bootstrap over placements: ``resamples`` draws of the placements with
replacement from a seeded generator (the same inputs give the same interval), the
statistic on each draw, and its 2.5th and 97.5th percentiles; draws in which either
variable is constant have no correlation and are left out (their share is reported).
A metric that does not vary, or fewer than ``MIN_PLACEMENTS`` placements, has no
correlation: ``None`` with the reason, never a number."""

import io

import numpy as np

MIN_PLACEMENTS = 3
RESAMPLES = 2000
LEVEL = 0.95


def _pearson_rows(x, y):
    """Pearson's r of each row pair of (B, n) ``x`` and ``y`` (NaN where one is
    constant)."""
    xc = x - x.mean(axis=1, keepdims=True)
    yc = y - y.mean(axis=1, keepdims=True)
    den = np.sqrt((xc * xc).sum(axis=1) * (yc * yc).sum(axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (xc * yc).sum(axis=1) / den
    r[~(den > 0)] = np.nan
    return np.clip(r, -1.0, 1.0)


def _ranks(a):
    from scipy.stats import rankdata

    return rankdata(a, axis=-1)  # ties share their average rank, as spearmanr ranks


def correlation(metric, ap, resamples=RESAMPLES, seed=0, level=LEVEL):
    """Correlation of ``ap`` (n,) with ``metric`` (n,) over n placements: a JSON-ready
    dict with ``n``, ``pearson`` and ``spearman`` (each ``{"r", "ci", "p"}`` or None),
    ``reason`` (why there is none) and ``bootstrap`` (draws, the share left out)."""
    from scipy.stats import pearsonr, spearmanr

    x, y = np.asarray(metric, np.float64), np.asarray(ap, np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError("metric and AP need one value per placement each")
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    out = {"n": int(len(x)), "pearson": None, "spearman": None, "reason": None,
           "bootstrap": {"resamples": int(resamples), "seed": int(seed), "level": level}}
    if len(x) < MIN_PLACEMENTS:
        out["reason"] = (f"{len(x)} placement(s) with both values; a correlation needs "
                         f"at least {MIN_PLACEMENTS}")
        return out
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        which = "the metric" if np.ptp(x) == 0 else "AP"
        out["reason"] = f"{which} is the same for every placement: nothing to correlate"
        return out
    idx = np.random.default_rng(seed).integers(0, len(x), size=(int(resamples), len(x)))
    bx, by = x[idx], y[idx]
    boot = {"pearson": _pearson_rows(bx, by),
            "spearman": _pearson_rows(_ranks(bx), _ranks(by))}
    tail = (1.0 - level) / 2 * 100
    for name, fn in (("pearson", pearsonr), ("spearman", spearmanr)):
        res = fn(x, y)
        draws = boot[name][np.isfinite(boot[name])]
        ci = ([float(v) for v in np.percentile(draws, [tail, 100 - tail])]
              if len(draws) else None)
        out[name] = {"r": float(res[0]), "p": float(res[1]), "ci": ci}
        out["bootstrap"][f"{name}_left_out"] = round(1.0 - len(draws) / len(boot[name]), 6)
    return out


def correlation_png(metric, ap, metric_label, ap_label="AP (%)", result=None, title=None):
    """PNG bytes of AP against the metric: one point per placement, the least-squares
    line, the coefficients (with their intervals) in the title; None without
    matplotlib. ``result`` is ``correlation(metric, ap)`` (worked out when None)."""
    from ..metrics.charts import DPI, pyplot

    plt = pyplot()
    if plt is None:
        return None
    x, y = np.asarray(metric, np.float64), np.asarray(ap, np.float64)
    res = correlation(x, y) if result is None else result
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=DPI)
    ok = np.isfinite(x) & np.isfinite(y)
    ax.scatter(x[ok], y[ok], s=28, color="#1f77b4", zorder=3, label="placement")
    if res["pearson"] is not None:
        k, b = np.polyfit(x[ok], y[ok], 1)
        xs = np.linspace(x[ok].min(), x[ok].max(), 50)
        ax.plot(xs, k * xs + b, color="#d62728", lw=1.5, label="least-squares fit")
        p, s = res["pearson"], res["spearman"]
        ci = lambda c: "" if c["ci"] is None else f" [{c['ci'][0]:.2f}, {c['ci'][1]:.2f}]"  # noqa: E731
        coef = (f"Pearson r = {p['r']:.2f}{ci(p)}, Spearman ρ = {s['r']:.2f}{ci(s)} "
                f"(n = {res['n']}, 95% bootstrap)")
    else:
        coef = f"no correlation: {res['reason']}"
    ax.set_title((title + "\n" if title else "") + coef, fontsize=9)
    ax.set_xlabel(metric_label)
    ax.set_ylabel(ap_label)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()
