/* The footprint's probe sub-rays, in C (footprint.py: probe_rays_numpy is the readable
 * reference this follows operation by operation, and gives the same bytes).
 *
 * rls_probe_sectors: per directed pair (i toward j) of rays across a depth edge, the
 * ring sector of i nearest j's direction: u, v = basis(d_i) (u = cross(d_i, up)
 * normalised, up = z or x for a vertical ray; v = cross(u, d_i)), delta = d_j - d_i,
 * phi = atan2(dot(delta, v) / vert, dot(delta, u) / h), k = rint(phi / sector) mod
 * RING; bit k of the ray's mask is set. numpy's dot of einsum("ck,ck->c") is summed
 * (x0 y0 + x2 y2) + x1 y1 and its norm (x0^2 + x1^2) + x2^2 (tested); atan2 may differ
 * from numpy's in the last bits, so a pair whose phi / sector lies within 1e-9 of a
 * half (or is not finite, or has delta 0) is left to numpy (listed in ``ambiguous``).
 *
 * rls_ring_rays: per ray of ``rows`` and per set bit k of its mask, in that order, the
 * sub-ray direction d + hc[k] u + vs[k] v normalised (ring_directions; hc and vs are
 * numpy's h cos(phi_k) and vert sin(phi_k), passed in). Built without fused
 * multiply-add; single-threaded (the pairs across edges are a few tens of thousands). */
#include <math.h>
#include <stdint.h>

#include "rls_threads.h"

#define RLS_PROBES_ABI 1
#define RING 6

typedef struct {
    int64_t n;                /* pairs across an edge */
    const int64_t *a, *b;     /* per pair: its two rays */
    const double *dir;        /* per ray: 3 doubles, unit, world */
    double h, vert;           /* the ring's half-axes (tangents, at least 1e-12) */
    double sector;            /* 2 pi / RING */
    uint8_t *mask;            /* per ray, or-ed: bit k = sector k probed */
    int64_t *ambiguous;       /* out, room for 2n: directed pairs left to numpy */
} sectors_t;

typedef struct {
    int64_t n;                /* rays */
    const int64_t *rows;      /* the rays */
    const uint8_t *mask;      /* per ray of rows: its sectors */
    const double *dir;        /* per ray of the frame: 3 doubles */
    const double *hc, *vs;    /* per sector: h cos(phi_k), vert sin(phi_k) */
    int64_t *ray;             /* out, per sub-ray: its ray */
    int64_t *sector;          /* out, per sub-ray: its sector */
    double *out;              /* out, per sub-ray: 3 doubles */
} ring_t;

static double dot_einsum(const double *x, const double *y) {
    return (x[0] * y[0] + x[2] * y[2]) + x[1] * y[1];
}

static double norm3(const double *x) {
    return sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]);
}

/* footprint._basis of one unit direction. */
static void basis(const double *d, double *u, double *v) {
    double up[3] = {0.0, 0.0, 1.0};
    if (fabs(d[2]) > 0.999) { up[0] = 1.0; up[2] = 0.0; }
    u[0] = d[1] * up[2] - d[2] * up[1];
    u[1] = d[2] * up[0] - d[0] * up[2];
    u[2] = d[0] * up[1] - d[1] * up[0];
    double nu = norm3(u);
    for (int k = 0; k < 3; k++) u[k] /= nu;
    v[0] = u[1] * d[2] - u[2] * d[1];
    v[1] = u[2] * d[0] - u[0] * d[2];
    v[2] = u[0] * d[1] - u[1] * d[0];
}

/* Returns how many directed pairs it left to numpy. */
RLS_EXPORT int64_t rls_probe_sectors(const sectors_t *s) {
    int64_t amb = 0;
    for (int64_t t = 0; t < 2 * s->n; t++) {
        int64_t i = t < s->n ? s->a[t] : s->b[t - s->n];
        int64_t j = t < s->n ? s->b[t] : s->a[t - s->n];
        const double *di = s->dir + 3 * i, *dj = s->dir + 3 * j;
        double u[3], v[3], delta[3];
        basis(di, u, v);
        for (int k = 0; k < 3; k++) delta[k] = dj[k] - di[k];
        double y = dot_einsum(delta, v) / s->vert, x = dot_einsum(delta, u) / s->h;
        double r = atan2(y, x) / s->sector;
        double frac = r - floor(r);
        if (!isfinite(r) || (x == 0.0 && y == 0.0) || fabs(frac - 0.5) < 1e-9) {
            s->ambiguous[amb++] = t;
            continue;
        }
        int64_t k = (int64_t)rint(r) % RING;
        if (k < 0) k += RING;
        s->mask[i] |= (uint8_t)(1u << k);
    }
    return amb;
}

/* Writes the sub-rays; returns how many. */
RLS_EXPORT int64_t rls_ring_rays(const ring_t *r) {
    int64_t m = 0;
    for (int64_t c = 0; c < r->n; c++) {
        int64_t i = r->rows[c];
        const double *d = r->dir + 3 * i;
        double u[3], v[3];
        basis(d, u, v);
        for (int k = 0; k < RING; k++) {
            if (!(r->mask[c] & (1u << k))) continue;
            double *o = r->out + 3 * m;
            for (int q = 0; q < 3; q++) o[q] = (d[q] + r->hc[k] * u[q]) + r->vs[k] * v[q];
            double n = norm3(o);
            for (int q = 0; q < 3; q++) o[q] /= n;
            r->ray[m] = i;
            r->sector[m] = k;
            m++;
        }
    }
    return m;
}

/* The interface version of the probe kernels (RLS_PROBES_ABI). */
RLS_EXPORT int rls_probes_abi(void) {
    return RLS_PROBES_ABI;
}
