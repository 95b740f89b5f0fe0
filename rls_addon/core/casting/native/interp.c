/* numpy's interp(x, xp, fp) in C, for the weather's false returns (weather.py:
 * false_return_ranges inverts a tabulated CDF at one uniform per ray).
 *
 * The same values as numpy's own (numpy/core/src/multiarray/compiled_base.c:
 * arr_interp, default left and right): j is the last index with xp[j] <= x, found by
 * bisection inside a bracket that a table over x's range gives (numpy bisects from the
 * previous point's index, which is slow for x in random order), and then the same
 * operations in the same order: fp[j] where xp[j] == x or j is the last, else
 * slope * (x - xp[j]) + fp[j] with slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
 * (NaN retried from j + 1, as numpy does). Built without fused multiply-add. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "rls_threads.h"

#define RLS_INTERP_ABI 1

/* The last j in [lo, hi) with xp[j] <= x, given xp[lo] <= x and (hi == len or)
 * x < xp[hi]. */
static int64_t last_le(const double *xp, double x, int64_t lo, int64_t hi) {
    while (hi - lo > 1) {
        int64_t mid = lo + (hi - lo) / 2;
        if (x >= xp[mid]) lo = mid;
        else hi = mid;
    }
    return lo;
}

static double at(const double *xp, const double *fp, int64_t len, double x, int64_t j) {
    if (j == len - 1 || xp[j] == x) return fp[j];
    double slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]);
    double v = slope * (x - xp[j]) + fp[j];
    if (isnan(v)) {
        v = slope * (x - xp[j + 1]) + fp[j + 1];
        if (isnan(v) && fp[j] == fp[j + 1]) v = fp[j];
    }
    return v;
}

/* out[i] = interp(x[i], xp, fp) for i < n; xp (len >= 2) does not decrease. Returns 0,
 * or -1 when it could not allocate its table (nothing written then). */
RLS_EXPORT int rls_interp(const double *x, int64_t n, const double *xp, const double *fp,
                          int64_t len, double *out) {
    /* tab[m]: the last j with xp[j] <= lo + m * h, m = 0..len (len buckets) */
    double lo = xp[0], hi = xp[len - 1], h = (hi - lo) / (double)len;
    int64_t buckets = h > 0.0 ? len : 0;
    int64_t *tab = malloc(sizeof(int64_t) * (size_t)(buckets + 1));
    if (!tab) return -1;
    for (int64_t m = 0, j = 0; m <= buckets; m++) {
        double edge = lo + (double)m * h;
        while (j + 1 < len && xp[j + 1] <= edge) j++;
        tab[m] = j;
    }
    for (int64_t i = 0; i < n; i++) {
        double v = x[i];
        if (isnan(v)) {
            out[i] = v;
            continue;
        }
        if (v < lo) {
            out[i] = fp[0];
            continue;
        }
        if (v > hi) {
            out[i] = fp[len - 1];
            continue;
        }
        int64_t a = 0, b = len;
        if (buckets) {
            double f = (v - lo) / h;
            int64_t m = f < (double)buckets ? (int64_t)f : buckets - 1;
            a = tab[m];
            b = tab[m + 1] + 1;
            if (!(xp[a] <= v)) a = 0;
            if (b < len && !(v < xp[b])) b = len;
        }
        out[i] = at(xp, fp, len, v, last_le(xp, v, a, b));
    }
    free(tab);
    return 0;
}

/* The interface version of rls_interp (RLS_INTERP_ABI). */
RLS_EXPORT int rls_interp_abi(void) {
    return RLS_INTERP_ABI;
}
