"""How well a cheap placement metric predicts detection quality: across placements,
the Pearson and Spearman correlation of AP with the metric (InfraD, InfraNUC, a
visibility share), each with a bootstrap 95% interval (the study draws them:
``study/ap_charts.py``).

The coefficients are scipy's (``scipy.stats.pearsonr``, ``spearmanr``). The interval is
the percentile bootstrap over placements: ``resamples`` draws of the placements with
replacement from a seeded generator (the same inputs give the same interval), the
statistic on each draw, and its 2.5th and 97.5th percentiles; draws in which either
variable is constant have no correlation and are left out (their share is reported).
A metric that does not vary, or fewer than ``MIN_PLACEMENTS`` placements, has no
correlation: ``None`` with the reason, never a number."""

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
