/* What each ray of a static scene's cast brought back, in C (rls_addon/core/returns.py:
 * static_returns_numpy is the readable reference this follows, and gives the same
 * bytes): per ray, whether it returns a point (it hit a triangle, at a range within
 * [rmin, rmax]) and the (object, material) row of the triangle it hit, gathered from
 * the scene's table (a miss, triangle -1, gets the table's last row, as numpy's take
 * gives it). One pass over the rays, single-threaded: numpy's four comparisons and its
 * gather, which slows threefold on the misses' negative rows, took 0.5 ms of a
 * Pandar64 frame. */
#include <stdint.h>

#include "rls_threads.h"

#define RLS_RETURNS_ABI 1

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

/* Returns 0, or -1 when a triangle index is outside the table (take's IndexError). */
RLS_EXPORT int64_t rls_static_returns(const returns_t *a) {
    for (int64_t i = 0; i < a->n; i++) {
        int64_t t = a->tri[i], row = t < 0 ? t + a->rows : t;
        if (row < 0 || row >= a->rows) return -1;
        a->surface[2 * i] = a->table[2 * row];
        a->surface[2 * i + 1] = a->table[2 * row + 1];
        double d = a->dist[i];
        a->valid[i] = t >= 0 && d >= a->rmin && d <= a->rmax;
    }
    return 0;
}

/* The interface version of rls_static_returns (RLS_RETURNS_ABI). */
RLS_EXPORT int rls_returns_abi(void) {
    return RLS_RETURNS_ABI;
}
