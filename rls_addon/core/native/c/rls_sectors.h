/* The footprint ring's geometry, shared by the probe kernels (probes.c) and the
 * depth-edge test that picks the probes as it goes (edges.c): footprint.py's _basis
 * and _sectors, operation by operation.
 *
 *     rls_basis(d, u, v)                      u = cross(d, up) normalised (up = z, or x
 *                                             for a vertical ray), v = cross(u, d)
 *     rls_sector(di, dj, h, vert, sector, &k) the ring sector k of ray i nearest the
 *                                             direction of ray j; 1 when it is left to
 *                                             numpy (see probes.c) */
#ifndef RLS_SECTORS_H
#define RLS_SECTORS_H

#include <math.h>
#include <stdint.h>

#define RLS_RING 6

/* numpy's einsum("ck,ck->c") sums (x0 y0 + x2 y2) + x1 y1 (tested). */
static double rls_dot_einsum(const double *x, const double *y) {
    return (x[0] * y[0] + x[2] * y[2]) + x[1] * y[1];
}

/* numpy's norm along an axis sums (x0^2 + x1^2) + x2^2. */
static double rls_norm3(const double *x) {
    return sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]);
}

static void rls_basis(const double *d, double *u, double *v) {
    double up[3] = {0.0, 0.0, 1.0};
    if (fabs(d[2]) > 0.999) { up[0] = 1.0; up[2] = 0.0; }
    u[0] = d[1] * up[2] - d[2] * up[1];
    u[1] = d[2] * up[0] - d[0] * up[2];
    u[2] = d[0] * up[1] - d[1] * up[0];
    double nu = rls_norm3(u);
    for (int k = 0; k < 3; k++) u[k] /= nu;
    v[0] = u[1] * d[2] - u[2] * d[1];
    v[1] = u[2] * d[0] - u[0] * d[2];
    v[2] = u[0] * d[1] - u[1] * d[0];
}

/* phi = atan2(dot(dj - di, v) / vert, dot(dj - di, u) / h), k = rint(phi / sector) mod
 * RING. atan2 may differ from numpy's in the last bits, so a pair whose phi / sector
 * lies within 1e-9 of a half (or is not finite, or has dj = di) returns 1: numpy
 * works out its sector. */
static int rls_sector(const double *di, const double *dj, double h, double vert,
                      double sector, int *k_out) {
    double u[3], v[3], delta[3];
    rls_basis(di, u, v);
    for (int k = 0; k < 3; k++) delta[k] = dj[k] - di[k];
    double y = rls_dot_einsum(delta, v) / vert, x = rls_dot_einsum(delta, u) / h;
    double r = atan2(y, x) / sector;
    double frac = r - floor(r);
    if (!isfinite(r) || (x == 0.0 && y == 0.0) || fabs(frac - 0.5) < 1e-9) return 1;
    int64_t k = (int64_t)rint(r) % RLS_RING;
    if (k < 0) k += RLS_RING;
    *k_out = (int)k;
    return 0;
}

#endif /* RLS_SECTORS_H */
