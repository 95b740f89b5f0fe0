/* Which neighbouring rays of a frame straddle a depth discontinuity, in C: one pass
 * over the pattern's neighbour pairs on a few threads (rls_depth_edges).
 *
 * rls_addon/core/physics/depth_edges.py (edges_numpy) is the readable reference this follows
 * operation by operation (the same sums in the same order, no fused multiply-add), so
 * both mark the same pairs: a pair is an edge when one ray hits and the other does
 * not, or when both hit, their ranges differ by more than the step and neither lies
 * within the step of the other's plane (the range each ray would have on the plane of
 * the other's hit, along its own direction).
 *
 * rls_edge_sectors tests the pairs in the same way and, for each pair across an edge,
 * sets the probe sectors of both of its rays (rls_sector, both ways: what
 * footprint.probe_rays does with the pairs rls_depth_edges marks), in one pass: the
 * pairs' rays are read once and no list of edge pairs is made. Threads set bits of one
 * mask with an atomic or; each share lists the directed pairs it leaves to numpy. */
#include <math.h>
#include <stdint.h>

#include "rls_sectors.h"
#include "rls_shares.h"

#define RLS_EDGES_ABI 2

typedef struct {
    int64_t n;                /* pairs */
    const int64_t *a, *b;     /* per pair: its two rays */
    const uint8_t *hit;       /* per ray: it hit something */
    const double *dist;       /* per ray: range (read only where it hit) */
    const double *normal;     /* per ray: 3 doubles */
    const double *dir;        /* per ray: 3 doubles, unit, world */
    const double *origin;     /* 3 doubles, or 3 per ray when origin_per_ray */
    int origin_per_ray;
    double step;              /* the depth step worth sampling (m) */
    uint8_t *edge;            /* per pair, written: 1 across a discontinuity */
} edges_t;

typedef struct {
    const edges_t *e;
    int64_t lo, hi;
} share_t;

static double dot3(const double *x, const double *y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
}

/* The range along d from o to the plane through o_p + d_p r_p with normal n
 * (edges_numpy's tj with several origins): dot(n, o_p + d_p r_p - o) / dot(n, d). */
static double on_plane(const double *n, const double *op, const double *dp, double rp,
                       const double *o, const double *d) {
    double v[3];
    for (int k = 0; k < 3; k++) v[k] = op[k] + dp[k] * rp - o[k];
    return dot3(n, v) / dot3(n, d);
}

static uint8_t is_edge(const edges_t *e, int64_t i, int64_t j) {
    if (e->hit[i] != e->hit[j]) return 1;
    if (!e->hit[i]) return 0;
    double ri = e->dist[i], rj = e->dist[j], step = e->step;
    if (!(fabs(ri - rj) > step)) return 0;
    const double *ni = e->normal + 3 * i, *nj = e->normal + 3 * j;
    const double *di = e->dir + 3 * i, *dj = e->dir + 3 * j;
    double ti, tj;
    if (!e->origin_per_ray) {
        tj = ri * dot3(ni, di) / dot3(ni, dj);
        ti = rj * dot3(nj, dj) / dot3(nj, di);
    } else {
        const double *oi = e->origin + 3 * i, *oj = e->origin + 3 * j;
        tj = on_plane(ni, oi, di, ri, oj, dj);
        ti = on_plane(nj, oj, dj, rj, oi, di);
    }
    return !(fabs(tj - rj) <= step) && !(fabs(ti - ri) <= step);
}

static void run_share(void *arg) {
    share_t *s = (share_t *)arg;
    const edges_t *e = s->e;
    for (int64_t k = s->lo; k < s->hi; k++) e->edge[k] = is_edge(e, e->a[k], e->b[k]);
}

typedef struct {
    const edges_t *e;         /* the pairs (e->edge is not written) */
    double h, vert;           /* the ring's half-axes (tangents, at least 1e-12) */
    double sector;            /* 2 pi / RING */
    uint8_t *mask;            /* per ray, or-ed: bit k = sector k probed */
    int64_t *ambiguous;       /* room for cap per share: directed pairs left to numpy,
                                 t (ray a toward b) or n + t (b toward a) */
    int64_t cap;
    int shares;               /* out: the shares the pairs were split into */
    int64_t n_ambiguous[RLS_MAX_SHARES];  /* out, per share (more than cap: cap + 1) */
    int64_t n_probes[RLS_MAX_SHARES];     /* out, per share: bits it set first */
} edge_sectors_t;

typedef struct {
    edge_sectors_t *s;
    int k;
    int64_t lo, hi;
} sector_share_t;

static void probe_toward(edge_sectors_t *s, int k, int64_t t, int64_t i, int64_t j) {
    int sec;
    const double *dir = s->e->dir;
    if (rls_sector(dir + 3 * i, dir + 3 * j, s->h, s->vert, s->sector, &sec)) {
        int64_t *n = &s->n_ambiguous[k];
        if (*n < s->cap) s->ambiguous[k * s->cap + *n] = t;
        if (*n <= s->cap) (*n)++;
        return;
    }
    uint8_t bit = (uint8_t)(1u << sec);
    if (!(__atomic_fetch_or(&s->mask[i], bit, __ATOMIC_RELAXED) & bit)) s->n_probes[k]++;
}

static void run_sector_share(void *arg) {
    sector_share_t *sh = (sector_share_t *)arg;
    edge_sectors_t *s = sh->s;
    const edges_t *e = s->e;
    for (int64_t t = sh->lo; t < sh->hi; t++) {
        int64_t i = e->a[t], j = e->b[t];
        if (!is_edge(e, i, j)) continue;
        probe_toward(s, sh->k, t, i, j);
        probe_toward(s, sh->k, e->n + t, j, i);
    }
}

/* Below this many pairs per share a thread costs more than it saves. */
#define MIN_SHARE 65536

/* Marks every pair (e->edge), on up to ``threads`` threads (the caller's among them). */
RLS_EXPORT void rls_depth_edges(const edges_t *e, int threads) {
    int shares = rls_share_count(e->n, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){e, 0, 0};
        rls_share_bounds(e->n, shares, k, &s[k].lo, &s[k].hi);
    }
    rls_run_shares(run_share, s, sizeof(share_t), shares);
}

/* Sets the probe sectors of the pairs across an edge (s->mask, zeroed by the caller),
 * on up to ``threads`` threads (the caller's among them). */
RLS_EXPORT void rls_edge_sectors(edge_sectors_t *s, int threads) {
    int shares = rls_share_count(s->e->n, threads, MIN_SHARE);
    sector_share_t sh[RLS_MAX_SHARES];
    s->shares = shares;
    for (int k = 0; k < shares; k++) {
        s->n_ambiguous[k] = s->n_probes[k] = 0;
        sh[k] = (sector_share_t){s, k, 0, 0};
        rls_share_bounds(s->e->n, shares, k, &sh[k].lo, &sh[k].hi);
    }
    rls_run_shares(run_sector_share, sh, sizeof(sector_share_t), shares);
}

/* The interface version of the depth-edge test (RLS_EDGES_ABI). */
RLS_EXPORT int rls_edges_abi(void) {
    return RLS_EDGES_ABI;
}
