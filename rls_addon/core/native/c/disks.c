/* A study candidate's points counted in the study's fixed disks, in C (rls_disk_counts).
 *
 * rls_addon/core/metrics/disk_counter.py (DiskCounter.counts_numpy) is the readable reference
 * this follows step by step, with the tables it works out once per study: each point's
 * grid cell (points beyond the grid, or not finite, clamped into the outer ring that no
 * disk reaches), a prefix sum of the points per cell for the disks' inside runs (two
 * look-ups per row of a disk), and the exact test dx * dx + dy * dy <= r * r (no fused
 * multiply-add) of each point in an edge cell against the disks whose circle crosses
 * that cell. The counts are integers: the same as the reference's, one for one. */
#include <stdint.h>
#include <string.h>

#include "rls_threads.h"

#define RLS_DISKS_ABI 1

typedef struct {
    int64_t n;                 /* points */
    const double *xy;          /* 2 per point */
    double lo_x, lo_y, h;      /* the grid's corner and cell size */
    int64_t nx, ny;            /* cells per row, rows */
    int64_t disks, rows;       /* disks; rows of the inside-run tables */
    const int64_t *span_lo;    /* (rows, disks): a disk's inside run in a row, */
    const int64_t *span_hi;    /*   as [first cell, cell after its last) */
    const int64_t *edge_start; /* per cell: its first entry in edge_disk */
    const int64_t *edge_count; /* per cell: how many disks' circles cross it */
    const int64_t *edge_disk;  /* the disks, grouped by cell */
    const double *centres;     /* 2 per disk */
    double r2;                 /* radius * radius */
    int64_t *cell;             /* scratch: n, each point's cell */
    int64_t *before;           /* scratch: nx * ny + 1 (cleared here): the prefix sum */
    int64_t *out;              /* disks, zeroed: the counts */
} disks_t;

/* The cell index along one axis of a coordinate already divided by the cell size:
 * truncated as numpy's astype(int64) truncates, after the reference's clamping
 * (below 0 or not a number: 0; beyond the last cell: the last). */
static int64_t cell_of(double f, int64_t count) {
    if (!(f >= 0)) return 0;
    if (f > (double)(count - 1)) f = (double)(count - 1);
    return (int64_t)f;
}

RLS_EXPORT void rls_disk_counts(const disks_t *a) {
    const int64_t cells = a->nx * a->ny;
    memset(a->before, 0, (size_t)(cells + 1) * sizeof(int64_t));
    for (int64_t i = 0; i < a->n; i++) {
        double fx = (a->xy[2 * i] - a->lo_x) / a->h;
        double fy = (a->xy[2 * i + 1] - a->lo_y) / a->h;
        int64_t c = cell_of(fy, a->ny) * a->nx + cell_of(fx, a->nx);
        a->cell[i] = c;
        a->before[c + 1]++;
    }
    for (int64_t c = 0; c < cells; c++) a->before[c + 1] += a->before[c];
    for (int64_t k = 0; k < a->rows; k++) {
        const int64_t *lo = a->span_lo + k * a->disks, *hi = a->span_hi + k * a->disks;
        for (int64_t d = 0; d < a->disks; d++) a->out[d] += a->before[hi[d]] - a->before[lo[d]];
    }
    for (int64_t i = 0; i < a->n; i++) {
        int64_t c = a->cell[i], j = a->edge_start[c], end = j + a->edge_count[c];
        double x = a->xy[2 * i], y = a->xy[2 * i + 1];
        for (; j < end; j++) {
            int64_t d = a->edge_disk[j];
            double dx = x - a->centres[2 * d], dy = y - a->centres[2 * d + 1];
            if (dx * dx + dy * dy <= a->r2) a->out[d]++;
        }
    }
}

/* The interface version of the disk counts (RLS_DISKS_ABI). */
RLS_EXPORT int rls_disks_abi(void) {
    return RLS_DISKS_ABI;
}
