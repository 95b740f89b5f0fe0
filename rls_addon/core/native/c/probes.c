/* The footprint's probe sub-rays, in C (footprint.py: probe_rays_numpy is the readable
 * reference this follows operation by operation, and gives the same bytes).
 *
 * rls_probe_sectors: per directed pair (i toward j) of rays across a depth edge, the
 * ring sector k of i nearest j's direction (rls_sector, rls_sectors.h); bit k of the
 * ray's mask is set. A pair rls_sector leaves to numpy (a sector on a boundary to the
 * last bits of atan2) is listed in ``ambiguous``.
 *
 * rls_ring_rays: per ray of ``rows`` (or, without rows, per ray of the frame whose mask
 * is not empty) and per set bit k of its mask, in that order, the sub-ray direction
 * d + hc[k] u + vs[k] v normalised (ring_directions; hc and vs are numpy's
 * h cos(phi_k) and vert sin(phi_k), passed in). Built without fused
 * multiply-add; single-threaded (the pairs across edges are a few tens of thousands). */
#include <math.h>
#include <stdint.h>

#include "rls_sectors.h"
#include "rls_threads.h"

#define RLS_PROBES_ABI 2
#define RING RLS_RING

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
    int64_t n;                /* rays of rows, or of the frame when rows is NULL */
    const int64_t *rows;      /* the rays, or NULL: every ray with a sector */
    const uint8_t *mask;      /* per ray of rows (of the frame): its sectors */
    const double *dir;        /* per ray of the frame: 3 doubles */
    const double *hc, *vs;    /* per sector: h cos(phi_k), vert sin(phi_k) */
    int64_t *ray;             /* out, per sub-ray: its ray */
    int64_t *sector;          /* out, per sub-ray: its sector */
    double *out;              /* out, per sub-ray: 3 doubles */
} ring_t;

/* Returns how many directed pairs it left to numpy. */
RLS_EXPORT int64_t rls_probe_sectors(const sectors_t *s) {
    int64_t amb = 0;
    for (int64_t t = 0; t < 2 * s->n; t++) {
        int64_t i = t < s->n ? s->a[t] : s->b[t - s->n];
        int64_t j = t < s->n ? s->b[t] : s->a[t - s->n];
        int k;
        if (rls_sector(s->dir + 3 * i, s->dir + 3 * j, s->h, s->vert, s->sector, &k)) {
            s->ambiguous[amb++] = t;
            continue;
        }
        s->mask[i] |= (uint8_t)(1u << k);
    }
    return amb;
}

/* Writes the sub-rays; returns how many. */
RLS_EXPORT int64_t rls_ring_rays(const ring_t *r) {
    int64_t m = 0;
    for (int64_t c = 0; c < r->n; c++) {
        if (!r->mask[c]) continue;
        int64_t i = r->rows ? r->rows[c] : c;
        const double *d = r->dir + 3 * i;
        double u[3], v[3];
        rls_basis(d, u, v);
        for (int k = 0; k < RING; k++) {
            if (!(r->mask[c] & (1u << k))) continue;
            double *o = r->out + 3 * m;
            for (int q = 0; q < 3; q++) o[q] = (d[q] + r->hc[k] * u[q]) + r->vs[k] * v[q];
            double n = rls_norm3(o);
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
