/* The per-hit stage of a frame, in C: from what each ray brought back to the point
 * records, in one pass over the rays on a few threads (rls_points_assemble).
 *
 * rls_addon/core/physics/assemble.py (assemble_numpy) is the readable reference this follows
 * operation by operation, so both write the same bits: per ray, the shading
 * (reflectivity x |cos incidence|, clipped to 0..1; a ghost's comes precomputed), the
 * range with its noise, CARLA's dropout from the uniforms the scan's generator drew
 * for every ray, and for each ray kept its point record written straight into the
 * output array (fields at the offsets the caller's dtype gives, -1: not written).
 * Random draws stay in numpy: the bytes do not depend on this file.
 *
 * Frames whose intensity needs exp, log or tanh (CARLA's attenuation, detection by the
 * LiDAR equation, weather, footprint echoes: libm's and numpy's differ in the last
 * bit) give their per-ray intensity, cosine and detection from numpy (inten_in,
 * dot_in, valid: assemble.py, _assemble_lidar_equation); the noise, the dropout and
 * the records are done here as for any frame, with the rows of false returns from the
 * air (medium) and each point's echo numbers (ret_index, num_ret) written as numpy's
 * _records writes them.
 *
 * One pass: the caller gives room for a record per ray; each thread takes a contiguous
 * share of the rays and writes its points from its share's first record on; then the
 * shares' points are moved down to follow each other (points keep the rays' order),
 * and the caller shrinks the arrays to the count returned. (An earlier version first
 * counted the points in a pass of its own: 0.6 ms of a 10 ms Pandar64 frame.) */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rls_shares.h"

#define RLS_POINTS_ABI 4

enum { F_X, F_Y, F_Z, F_RANGE, F_INTENSITY, F_RING, F_TIME, F_LABEL, F_INSTANCE, F_GHOST,
       F_RETURN_INDEX, F_NUM_RETURNS, N_FIELDS };

typedef struct {
    int64_t n;                /* rays */
    const double *dist;       /* per ray: range to what sent the light back */
    const uint8_t *valid;     /* per ray: it returned something within range */
    const int32_t *surface;   /* per ray: object, material index (2 int32) */
    const double *normal;     /* per ray: 3 doubles */
    const double *dir;        /* per ray: 3 doubles, unit, world */
    const uint8_t *ghost;     /* per ray: 1 for a ghost, or NULL */
    const double *ghost_dot;  /* per ray: cos to the ghost's last leg (ghost rows) */
    const double *ghost_int;  /* per ray: the ghost's intensity (ghost rows) */
    const double *refl;       /* per material: reflectivity */
    const uint32_t *label;    /* per object */
    const uint32_t *instance; /* per object */
    const float *noise;       /* per ray: range noise, or NULL */
    const double *u_general;  /* per ray: uniform of the general dropout, or NULL */
    double general_rate;
    const double *u_low;      /* per ray: uniform of the low-intensity dropout, or NULL */
    double limit, zero;
    int world;                /* 1: world frame (dir, origin); 0: sensor frame (cols) */
    const double *origin;     /* world: 3 doubles, or 3 per ray when origin_per_ray */
    int origin_per_ray;
    const double *cols[3];    /* sensor: the pattern's direction columns */
    const uint16_t *ring;     /* per ray */
    const double *time;       /* per ray */
    int64_t offsets[N_FIELDS];  /* byte offset of each field in a record, -1: absent */
    int64_t itemsize;
    const double *inten_in;   /* per ray: the intensity, given (with dot_in), or NULL */
    const double *dot_in;     /* per ray: cos between normal and ray, given, or NULL */
    const uint8_t *medium;    /* per ray: 1 for a false return from the air, or NULL */
    uint32_t medium_label;    /* the label of those (instance 0, no ghost) */
    const uint8_t *ret_index; /* per ray: the point's return index, or NULL (1) */
    const uint8_t *num_ret;   /* per ray: its pulse's number of returns, or NULL (1) */
    uint8_t *out;             /* records, room for n */
    int64_t *index;           /* per point: its ray (room for n) */
    uint8_t *back;            /* per point: 1 when it lies on the back of its face (room
                                 for n) */
} points_t;

typedef struct {
    const points_t *a;
    int64_t lo, hi, count;
} share_t;

/* Whether ray i returns a point, with its range and intensity (assemble.py:
 * assemble_numpy, _noise_and_dropout). */
static int shade(const points_t *a, int64_t i, double *range, double *inten, double *dot) {
    const double *nrm = a->normal + 3 * i, *d = a->dir + 3 * i;
    int g = a->ghost && a->ghost[i];
    double c, v;
    if (a->inten_in) {
        c = a->dot_in[i];
        v = a->inten_in[i];
    } else if (g) {
        c = a->ghost_dot[i];
        v = a->ghost_int[i];
    } else {
        c = nrm[0] * d[0] + nrm[1] * d[1] + nrm[2] * d[2];
        v = a->refl[a->surface[2 * i + 1]] * fabs(c);
        v = v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v);
    }
    *dot = c;
    *inten = v;
    double r = a->noise ? a->dist[i] + (double)a->noise[i] : a->dist[i];
    *range = r;
    if (!a->valid[i]) return 0;
    if (a->u_general && !(a->u_general[i] >= a->general_rate)) return 0;
    if (a->u_low) {
        double p = (a->zero / a->limit) * v + (1.0 - a->zero);
        if (v <= a->limit && !(a->u_low[i] < p)) return 0;
    }
    return r > 0;
}

#define PUT(field, type, value)                                         \
    do {                                                                \
        if (a->offsets[field] >= 0) {                                   \
            type tmp_ = (value);                                        \
            memcpy(rec + a->offsets[field], &tmp_, sizeof(tmp_));       \
        }                                                               \
    } while (0)

/* Writes the points of rays [lo, hi) from record lo on; counts them. */
static void write_share(void *arg) {
    share_t *s = (share_t *)arg;
    const points_t *a = s->a;
    int64_t p = s->lo;
    double r, v, dot;
    for (int64_t i = s->lo; i < s->hi; i++) {
        if (!shade(a, i, &r, &v, &dot)) continue;
        uint8_t *rec = a->out + p * a->itemsize;
        int32_t obj = a->surface[2 * i];
        if (a->world) {
            const double *d = a->dir + 3 * i;
            const double *o = a->origin + (a->origin_per_ray ? 3 * i : 0);
            PUT(F_X, double, d[0] * r + o[0]);
            PUT(F_Y, double, d[1] * r + o[1]);
            PUT(F_Z, double, d[2] * r + o[2]);
        } else {
            PUT(F_X, double, a->cols[0][i] * r);
            PUT(F_Y, double, a->cols[1][i] * r);
            PUT(F_Z, double, a->cols[2][i] * r);
        }
        PUT(F_RANGE, double, r);
        PUT(F_INTENSITY, float, (float)v);
        PUT(F_RING, uint16_t, a->ring[i]);
        PUT(F_TIME, double, a->time[i]);
        int air = a->medium && a->medium[i];
        PUT(F_LABEL, uint32_t, air ? a->medium_label : a->label[obj]);
        PUT(F_INSTANCE, uint32_t, air ? 0u : a->instance[obj]);
        PUT(F_GHOST, uint8_t, (!air && a->ghost) ? a->ghost[i] : 0);
        PUT(F_RETURN_INDEX, uint8_t, a->ret_index ? a->ret_index[i] : 1);
        PUT(F_NUM_RETURNS, uint8_t, a->num_ret ? a->num_ret[i] : 1);
        a->index[p] = i;
        a->back[p] = dot > 0;
        p++;
    }
    s->count = p - s->lo;
}

/* Below this many rays per share a thread costs more than it saves. */
#define MIN_SHARE 16384

/* The records of the rays kept, in ray order, from the first record of out, index and
 * back on (each with room for n); returns how many. */
RLS_EXPORT int64_t rls_points_assemble(const points_t *a, int threads) {
    int shares = rls_share_count(a->n, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){a, 0, 0, 0};
        rls_share_bounds(a->n, shares, k, &s[k].lo, &s[k].hi);
    }
    rls_run_shares(write_share, s, sizeof(share_t), shares);
    int64_t at = s[0].count;
    for (int k = 1; k < shares; k++) {
        int64_t c = s[k].count, lo = s[k].lo;
        if (c && lo != at) {
            memmove(a->out + at * a->itemsize, a->out + lo * a->itemsize, c * a->itemsize);
            memmove(a->index + at, a->index + lo, c * sizeof(int64_t));
            memmove(a->back + at, a->back + lo, c);
        }
        at += c;
    }
    return at;
}

/* The interface version of the per-hit stage (RLS_POINTS_ABI). */
RLS_EXPORT int rls_points_abi(void) {
    return RLS_POINTS_ABI;
}
