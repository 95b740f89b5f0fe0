/* What each ray of a static scene's cast brought back, in C (rls_addon/core/world/returns.py:
 * static_returns_numpy is the readable reference this follows, and gives the same
 * bytes): per ray, whether it returns a point (it hit a triangle, at a range within
 * [rmin, rmax]) and the (object, material) row of the triangle it hit, gathered from
 * the scene's table (a miss, triangle -1, gets the table's last row, as numpy's take
 * gives it). One pass over the rays, in shares on a few threads: the gather is bound by
 * memory latency on a large scene (8 MB of rows for the 1M-triangle bench street);
 * numpy's four comparisons and its gather, which slows threefold on the misses'
 * negative rows, took 0.5-1.2 ms of a Pandar64 frame. */
#include <stdint.h>

#include "rls_shares.h"

#define RLS_RETURNS_ABI 2

typedef struct {
    int64_t n;              /* rays */
    const double *dist;     /* per ray: range of its hit */
    const int64_t *tri;     /* per ray: the scene's triangle it hit, or -1 */
    const int32_t *table;   /* rows x 2: (object, material) per triangle */
    int64_t rows;
    double rmin, rmax;
    uint8_t *valid;         /* out, per ray */
    int32_t *surface;       /* out, n x 2 */
} returns_t;

/* How many rays ahead a share asks for its table rows. */
#define AHEAD 32

typedef struct {
    const returns_t *a;
    int64_t lo, hi;  /* this share's rays */
    int bad;         /* out: a triangle outside the table */
} share_t;

static void run_share(void *arg) {
    share_t *s = (share_t *)arg;
    const returns_t *a = s->a;
    for (int64_t i = s->lo; i < s->hi; i++) {
        if (i + AHEAD < s->hi) {  /* the rows are scattered: ask for them early */
            int64_t ahead = a->tri[i + AHEAD];
            if (ahead >= 0 && ahead < a->rows) __builtin_prefetch(a->table + 2 * ahead);
        }
        int64_t t = a->tri[i], row = t < 0 ? t + a->rows : t;
        if (row < 0 || row >= a->rows) {
            s->bad = 1;
            return;
        }
        a->surface[2 * i] = a->table[2 * row];
        a->surface[2 * i + 1] = a->table[2 * row + 1];
        double d = a->dist[i];
        a->valid[i] = t >= 0 && d >= a->rmin && d <= a->rmax;
    }
}

/* Below this many rays per share a thread costs more than it saves. */
#define MIN_SHARE 16384

/* Returns 0, or -1 when a triangle index is outside the table (take's IndexError), on
 * up to ``threads`` threads (the caller's among them; each ray's row is its own). */
RLS_EXPORT int64_t rls_static_returns(const returns_t *a, int threads) {
    int shares = rls_share_count(a->n, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){a, 0, 0, 0};
        rls_share_bounds(a->n, shares, k, &s[k].lo, &s[k].hi);
    }
    rls_run_shares(run_share, s, sizeof(share_t), shares);
    for (int k = 0; k < shares; k++)
        if (s[k].bad) return -1;
    return 0;
}

/* The interface version of rls_static_returns (RLS_RETURNS_ABI). */
RLS_EXPORT int rls_returns_abi(void) {
    return RLS_RETURNS_ABI;
}
