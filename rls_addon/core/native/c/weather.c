/* The false returns from the air of a frame, in C (weather.py: false_returns_numpy is
 * the readable reference this follows, and gives the same bytes): per ray, when its
 * uniform ``u_medium`` is below the false-return probability, the range at which its
 * uniform ``u_range`` inverts the tabulated CDF, kept where it is nearer than the
 * first surface the ray meets.
 *
 * The inversion is numpy's interp(u, cdf, x) to the bit (numpy/core/src/multiarray/
 * compiled_base.c: arr_interp, default left and right): j is the last index with
 * cdf[j] <= u, found by bisection inside a bracket that a table over the CDF's range
 * gives (numpy bisects from the previous point's index, slow for uniforms in random
 * order: 11 ms for a frame of 133k rays), then the same operations in the same order:
 * x[j] where cdf[j] == u or j is the last, else slope * (u - cdf[j]) + x[j] with
 * slope = (x[j + 1] - x[j]) / (cdf[j + 1] - cdf[j]), worked out once per segment
 * (NaN retried from j + 1, as numpy does); the range is 1.0 / that. Built without
 * fused multiply-add. One pass over the rays, in shares on a few threads (about 2 ms
 * on one thread, 1.2 ms on two, for a frame of 133k rays in fog of 50 m visibility). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rls_shares.h"

#define RLS_WEATHER_ABI 2

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

/* interp(x, xp, fp) with j = last_le(x). */
static double at(const double *xp, const double *fp, const double *slopes, int64_t len,
                 double x, int64_t j) {
    if (j == len - 1 || xp[j] == x) return fp[j];
    double slope = slopes[j];
    double v = slope * (x - xp[j]) + fp[j];
    if (isnan(v)) {
        v = slope * (x - xp[j + 1]) + fp[j + 1];
        if (isnan(v) && fp[j] == fp[j + 1]) v = fp[j];
    }
    return v;
}

typedef struct {
    int64_t n;                /* rays */
    const double *u_medium;   /* per ray: does the air send a false return */
    const double *u_range;    /* per ray: its range */
    double p;                 /* the probability of a false return */
    const uint8_t *hit;       /* per ray: it meets a surface ... */
    const double *dist;       /* ... at this range */
    const double *cdf, *x;    /* the CDF of 1 / range tabulated at x (len points) */
    int64_t len;
    int64_t *rows;            /* out, room for n: the rays with a false return */
    double *ranges;           /* out, room for n: its range */
} air_t;

/* The bucket table of the CDF: tab[m] is the last j with xp[j] <= lo + m * h, m = 0..len
 * (len buckets): where to look for u in bucket m (any bracket found is checked, so
 * rounding here only costs time). */
typedef struct {
    const air_t *a;
    const int64_t *tab;
    const double *slopes;  /* per segment j: (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]) */
    int64_t buckets;
    double lo, hi, per_bucket;
    int64_t start, end;  /* this share's rays */
    int64_t count;       /* out: its false returns, written from rows[start] on */
} share_t;

static void run_share(void *arg) {
    share_t *s = (share_t *)arg;
    const air_t *a = s->a;
    const double *xp = a->cdf, *fp = a->x;
    int64_t len = a->len, buckets = s->buckets, count = 0;
    double lo = s->lo, hi = s->hi;
    int64_t *rows = a->rows + s->start;
    double *ranges = a->ranges + s->start;
    for (int64_t i = s->start; i < s->end; i++) {
        if (!(a->u_medium[i] < a->p)) continue;
        double u = a->u_range[i], v;
        if (isnan(u)) {
            v = u;
        } else if (u < lo) {
            v = fp[0];
        } else if (u > hi) {
            v = fp[len - 1];
        } else {
            int64_t b0 = 0, e = len;
            if (buckets) {
                double f = (u - lo) * s->per_bucket;
                int64_t m = f < (double)buckets ? (int64_t)f : buckets - 1;
                b0 = s->tab[m];
                e = s->tab[m + 1] + 1;
                if (!(xp[b0] <= u)) b0 = 0;
                if (e < len && !(u < xp[e])) e = len;
            }
            v = at(xp, fp, s->slopes, len, u, last_le(xp, u, b0, e));
        }
        double r = 1.0 / v;
        if (r < (a->hit[i] ? a->dist[i] : INFINITY)) {
            rows[count] = i;
            ranges[count] = r;
            count++;
        }
    }
    s->count = count;
}

/* Below this many rays per share a thread costs more than it saves. */
#define MIN_SHARE 16384

/* Writes the rays with a false return and their ranges, in ray order, on up to
 * ``threads`` threads (the caller's among them): each share of rays writes its own
 * from its first ray's slot on, then the shares are moved down to follow each other.
 * Returns how many, or -1 when it could not allocate its table (nothing written). */
RLS_EXPORT int64_t rls_false_returns(const air_t *a, int threads) {
    const double *xp = a->cdf;
    int64_t len = a->len;
    double lo = xp[0], hi = xp[len - 1], h = (hi - lo) / (double)len;
    int64_t buckets = h > 0.0 ? len : 0;
    int64_t *tab = malloc(sizeof(int64_t) * (size_t)(buckets + 1));
    double *slopes = malloc(sizeof(double) * (size_t)(len > 1 ? len - 1 : 1));
    if (!tab || !slopes) {
        free(tab);
        free(slopes);
        return -1;
    }
    for (int64_t m = 0, j = 0; m <= buckets; m++) {
        double edge = lo + (double)m * h;
        while (j + 1 < len && xp[j + 1] <= edge) j++;
        tab[m] = j;
    }
    /* once per segment, not per false return (as numpy's interp does for long inputs) */
    const double *fp = a->x;
    for (int64_t j = 0; j + 1 < len; j++) slopes[j] = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]);
    int shares = rls_share_count(a->n, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){a, tab, slopes, buckets, lo, hi, buckets ? 1.0 / h : 0.0, 0, 0, 0};
        rls_share_bounds(a->n, shares, k, &s[k].start, &s[k].end);
    }
    rls_run_shares(run_share, s, sizeof(share_t), shares);
    int64_t count = s[0].count;
    for (int k = 1; k < shares; k++) {
        if (s[k].count && s[k].start != count) {
            memmove(a->rows + count, a->rows + s[k].start, sizeof(int64_t) * (size_t)s[k].count);
            memmove(a->ranges + count, a->ranges + s[k].start, sizeof(double) * (size_t)s[k].count);
        }
        count += s[k].count;
    }
    free(tab);
    free(slopes);
    return count;
}

/* The interface version of rls_false_returns (RLS_WEATHER_ABI). */
RLS_EXPORT int rls_weather_abi(void) {
    return RLS_WEATHER_ABI;
}
