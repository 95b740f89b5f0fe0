"""Correlation of AP with a placement metric (``evaluate/correlation.py``): scipy's
coefficients, a seeded percentile bootstrap checked against a plain loop, and no
number where there is nothing to correlate."""

import numpy as np
import pytest
from scipy.stats import pearsonr, spearmanr

from rls_addon.core.evaluate import correlation as corr


def test_a_line_correlates_exactly():
    x = np.array([1.0, 2.0, 4.0, 8.0, 9.0])
    res = corr.correlation(x, 3 * x + 1)
    assert res["n"] == 5 and res["reason"] is None
    for name in ("pearson", "spearman"):
        assert res[name]["r"] == pytest.approx(1.0, abs=1e-12)
        assert res[name]["ci"] == pytest.approx([1.0, 1.0], abs=1e-12)


def test_coefficients_are_scipys_and_spearman_sees_monotone_curves():
    x = np.array([0.5, 1.0, 2.0, 3.0, 5.0, 8.0])
    y = np.exp(x / 2)  # monotone, not a line
    res = corr.correlation(x, y)
    assert res["pearson"]["r"] == pytest.approx(pearsonr(x, y)[0], abs=1e-12)
    assert res["pearson"]["r"] < 0.99
    assert res["spearman"]["r"] == pytest.approx(1.0, abs=1e-12)
    down = corr.correlation(x, -y)
    assert down["spearman"]["r"] == pytest.approx(-1.0, abs=1e-12)


def test_the_bootstrap_interval_is_the_plain_loops():
    """The vectorised bootstrap gives the percentiles a loop over scipy gives on the
    same seeded draws (draws with a constant side left out)."""
    rng = np.random.default_rng(7)
    x = rng.normal(size=9)
    y = 0.6 * x + rng.normal(scale=0.8, size=9)
    res = corr.correlation(x, y, resamples=400, seed=3)
    idx = np.random.default_rng(3).integers(0, 9, size=(400, 9))
    for name, fn in (("pearson", pearsonr), ("spearman", spearmanr)):
        vals = []
        for row in idx:
            a, b = x[row], y[row]
            if np.ptp(a) > 0 and np.ptp(b) > 0:
                vals.append(fn(a, b)[0])
        want = np.percentile(vals, [2.5, 97.5])
        assert res[name]["ci"] == pytest.approx(list(want), abs=1e-9)
        assert res[name]["ci"][0] <= res[name]["r"] <= res[name]["ci"][1]
        assert res["bootstrap"][f"{name}_left_out"] == pytest.approx(1 - len(vals) / 400)
    assert corr.correlation(x, y, resamples=400, seed=3) == res  # seeded: the same


def test_nothing_to_correlate_gives_no_number():
    few = corr.correlation([1.0, 2.0], [0.3, 0.4])
    assert few["pearson"] is None and "at least 3" in few["reason"]
    flat = corr.correlation([2.0, 2.0, 2.0, 2.0], [0.1, 0.5, 0.2, 0.9])
    assert flat["pearson"] is None and flat["spearman"] is None
    assert "the metric is the same for every placement" in flat["reason"]
    flat_ap = corr.correlation([1.0, 2.0, 3.0], [0.5, 0.5, 0.5])
    assert "AP is the same" in flat_ap["reason"]
    nan = corr.correlation([1.0, np.nan, 3.0, 4.0], [0.1, 0.2, np.nan, 0.4])
    assert nan["n"] == 2 and nan["pearson"] is None
    with pytest.raises(ValueError):
        corr.correlation([1.0, 2.0, 3.0], [1.0, 2.0])
