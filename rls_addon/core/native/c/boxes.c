/* What every ground-truth box of a frame counts, in C (rls_box_counts): over the rays
 * toward each box (segments of the rays sorted by direction cell, see
 * rls_addon/core/output/ray_cells.py), the rays whose path crosses the box within range
 * and whether each reached the box's object or something in front of it, and the real
 * points (not ghosts) on those rays that lie inside the box grown by a margin.
 *
 * rls_addon/core/output/box_counts.py (box_counts_numpy: visibility, points_inside) is
 * the readable reference this follows operation by operation: the offset from the
 * box's centre turned into its axes as ((x * r0j + y * r1j) + z * r2j), the slab test
 * with 1 / d, a 0 * inf (NaN) slab bound taken as -inf / +inf, and the same
 * comparisons; the library is built without fused multiply-add, so both make the same
 * decisions and the counts are the reference's, one for one. Segments are split into
 * shares on a few threads, each with counts of its own, summed at the end. A segment's
 * rays lie scattered over the frame's arrays (a direction cell holds a few rays of
 * each of many firings), so each share asks for a ray's data AHEAD rays before it
 * tests it: every test waited on memory otherwise (a traffic frame's counts, 157k
 * box-ray pairs, 4.8-6.2 -> 2.8-4.4 ms with nothing beside them and 13.6-15.0 ->
 * 8.4-10.9 ms beside the next frame's scan; bench/drive_costs.py's traffic drive). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rls_shares.h"

#define RLS_BOXES_ABI 1

typedef struct {
    int64_t boxes;
    const double *centre;     /* boxes x 3 */
    const double *rot;        /* boxes x 9: row-major 3x3, its columns the box's axes */
    const double *half;       /* boxes x 3: half the size */
    const double *grown;      /* boxes x 3: half the size + the points' margin */
    const int32_t *object;    /* boxes: its object's index into the rays' objects */
    const double *reach;      /* boxes: a radius around the centre that holds the box
                                 grown by the margin, padded (see below) */
    int64_t segments;
    const int64_t *seg_box;   /* per segment: its box */
    const int64_t *seg_lo;    /* per segment: its first position in order */
    const int64_t *seg_hi;    /*   and the position after its last */
    const int64_t *order;     /* the rays by direction cell */
    const double *origins;    /* 3 per ray, or one origin (one_origin) */
    int64_t one_origin;
    const double *dirs;       /* 3 per ray */
    const int32_t *hit;       /* per ray: the object of its first hit, -1: none */
    const double *dist;       /* per ray: the range of that hit */
    double rmax;
    const int64_t *pstart;    /* rays + 1: ray r's points are point_order[pstart[r]..] */
    const int64_t *point_order;
    const double *range;      /* per point */
    const uint8_t *real;      /* per point: not a ghost */
    int64_t *seen;            /* out, boxes: rays on the box that reached its object */
    int64_t *blocked;         /* out, boxes: rays on the box stopped in front of it */
    int64_t *inside;          /* out, boxes: real points inside the grown box */
} boxes_t;

typedef struct {
    const boxes_t *a;
    int64_t lo, hi;  /* this share's segments */
    int64_t *seen, *blocked, *inside;  /* this share's counts */
} share_t;

/* v turned into the axes of rotation r (row-major): v @ r, the sums in numpy's order. */
static void in_axes(const double *v, const double *r, double *out) {
    for (int j = 0; j < 3; j++) out[j] = v[0] * r[j] + v[1] * r[3 + j] + v[2] * r[6 + j];
}

/* How many rays ahead a share asks for their data. */
#define AHEAD 16

static double min2(double a, double b) { return b < a ? b : a; }
static double max2(double a, double b) { return b > a ? b : a; }

static void run_share(void *arg) {
    share_t *s = (share_t *)arg;
    const boxes_t *a = s->a;
    for (int64_t g = s->lo; g < s->hi; g++) {
        const int64_t b = a->seg_box[g];
        const double *c = a->centre + 3 * b, *r = a->rot + 9 * b;
        const double *half = a->half + 3 * b, *grown = a->grown + 3 * b;
        const int64_t seg_hi = a->seg_hi[g];
        for (int64_t p = a->seg_lo[g]; p < seg_hi; p++) {
            if (p + AHEAD < seg_hi) {  /* the rays are scattered: ask for them early */
                const int64_t next = a->order[p + AHEAD];
                __builtin_prefetch(a->dirs + 3 * next);
                __builtin_prefetch(a->dirs + 3 * next + 2);
                if (!a->one_origin) {
                    __builtin_prefetch(a->origins + 3 * next);
                    __builtin_prefetch(a->origins + 3 * next + 2);
                }
                __builtin_prefetch(a->hit + next);
                __builtin_prefetch(a->dist + next);
                __builtin_prefetch(a->pstart + next);
            }
            if (p + AHEAD / 2 < seg_hi) {  /* and, nearer, for their points */
                const int64_t next = a->order[p + AHEAD / 2];
                const int64_t q = a->pstart[next];
                if (q < a->pstart[next + 1]) {
                    const int64_t pt = a->point_order[q];
                    __builtin_prefetch(a->range + pt);
                    __builtin_prefetch(a->real + pt);
                }
            }
            const int64_t ray = a->order[p];
            const double *o = a->one_origin ? a->origins : a->origins + 3 * ray;
            const double *d = a->dirs + 3 * ray;
            double rel[3] = {o[0] - c[0], o[1] - c[1], o[2] - c[2]};
            /* A ray whose line passes farther than the reach from the centre, or that
             * leaves it behind, crosses neither box and has no point in them: no test
             * below can count it (the reach holds both with a margin far above the
             * rounding of these sums). */
            double along = -(rel[0] * d[0] + rel[1] * d[1] + rel[2] * d[2]);
            double rr = a->reach[b];
            if (along + rr < 0) continue;
            double perp2 = rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2] - along * along;
            if (perp2 > rr * rr) continue;
            /* The slab test, axis by axis, each axis' offset and direction turned into
             * the box's axes as in_axes does: t_in only grows and t_out only shrinks
             * (exact maxima and minima, in any order of the axes), so once the ray
             * cannot be on the box (t_in > t_out, t_out <= 0 or t_in > rmax) the axes
             * left cannot change that and are skipped; z first, the axis that turns
             * most rays away from a box beside or below the sensor. */
            double t_in = -INFINITY, t_out = INFINITY;
            int on = 1;
            for (int i = 0; i < 3 && on; i++) {
                const int k = (i + 2) % 3;  /* z first: height cuts most rays */
                const double olk = rel[0] * r[k] + rel[1] * r[3 + k] + rel[2] * r[6 + k];
                const double dlk = d[0] * r[k] + d[1] * r[3 + k] + d[2] * r[6 + k];
                double inv = 1.0 / dlk;
                double t1 = (-half[k] - olk) * inv, t2 = (half[k] - olk) * inv;
                if (t1 != t1) t1 = -INFINITY;
                if (t2 != t2) t2 = INFINITY;
                t_in = max2(t_in, min2(t1, t2));
                t_out = min2(t_out, max2(t1, t2));
                on = t_in <= t_out && t_out > 0 && t_in <= a->rmax;
            }
            if (on) {
                const int32_t h = a->hit[ray];
                if (h == a->object[b]) s->seen[b]++;
                else if (h >= 0 && a->dist[ray] < max2(t_in, 0.0) + 1e-6) s->blocked[b]++;
            }
            for (int64_t q = a->pstart[ray]; q < a->pstart[ray + 1]; q++) {
                const int64_t pt = a->point_order[q];
                if (!a->real[pt]) continue;
                const double range = a->range[pt];
                /* a point farther along its ray from the centre's foot than the reach
                 * is farther than the reach from the centre: not in the grown box */
                if (range - along > rr || along - range > rr) continue;
                double w[3], l[3];
                for (int k = 0; k < 3; k++) w[k] = (o[k] + d[k] * range) - c[k];
                in_axes(w, r, l);
                if (((l[0] < 0 ? -l[0] : l[0]) <= grown[0]) && ((l[1] < 0 ? -l[1] : l[1]) <= grown[1])
                    && ((l[2] < 0 ? -l[2] : l[2]) <= grown[2]))
                    s->inside[b]++;
            }
        }
    }
}

/* Below this many segments per share a thread costs more than it saves (the caller
 * cuts segments to at most a few thousand rays). */
#define MIN_SHARE 16

/* Counts per box into seen, blocked and inside (zeroed here), on up to ``threads``
 * threads (the caller's among them). */
RLS_EXPORT void rls_box_counts(const boxes_t *a, int threads) {
    int shares = rls_share_count(a->segments, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    memset(a->seen, 0, (size_t)a->boxes * sizeof(int64_t));
    memset(a->blocked, 0, (size_t)a->boxes * sizeof(int64_t));
    memset(a->inside, 0, (size_t)a->boxes * sizeof(int64_t));
    /* share 0 counts in place, the others in counts of their own */
    int64_t *extra = shares > 1 ? calloc((size_t)(shares - 1) * 3 * (size_t)a->boxes,
                                         sizeof(int64_t)) : NULL;
    if (extra == NULL) shares = 1;
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){a, 0, 0, a->seen, a->blocked, a->inside};
        if (k > 0) {
            int64_t *mine = extra + (size_t)(k - 1) * 3 * (size_t)a->boxes;
            s[k].seen = mine;
            s[k].blocked = mine + a->boxes;
            s[k].inside = mine + 2 * a->boxes;
        }
        rls_share_bounds(a->segments, shares, k, &s[k].lo, &s[k].hi);
    }
    rls_run_shares(run_share, s, sizeof(share_t), shares);
    for (int k = 1; k < shares; k++)
        for (int64_t b = 0; b < a->boxes; b++) {
            a->seen[b] += s[k].seen[b];
            a->blocked[b] += s[k].blocked[b];
            a->inside[b] += s[k].inside[b];
        }
    free(extra);
}

/* The interface version of rls_box_counts (RLS_BOXES_ABI). */
RLS_EXPORT int rls_boxes_abi(void) {
    return RLS_BOXES_ABI;
}

/* The real points of every box, grouped (rls_own_points): a scan's points are records
 * (a numpy structured array) with the instance id (uint32), the ghost flag (uint8)
 * and the firing time (float64) at byte offsets of their own, possibly unaligned
 * (read with memcpy). A point whose id is one of the boxes' sorted unique ``keys``
 * and that is not a ghost belongs to that key's group; the groups' times come out
 * one group after another, each in the points' order, ``first`` the groups' starts
 * (keys + 1). ground_truth._own_groups_numpy is the reference this follows: the
 * same groups in the same order (a stable sort of the group numbers). */
#define RLS_OWN_POINTS_ABI 1

typedef struct {
    int64_t n;             /* points */
    const char *base;      /* the first point's record */
    int64_t stride;        /* bytes from one record to the next */
    int64_t off_instance, off_ghost, off_time;
    int64_t keys;          /* how many keys */
    const uint32_t *key;   /* sorted, unique */
    int32_t *group;        /* scratch, n: each point's group, -1: none */
    int64_t *next;         /* scratch, keys: each group's next slot in times */
    int64_t *first;        /* out, keys + 1 */
    double *times;         /* out, up to n: the groups' times */
} own_points_t;

/* Bits of a point id's low 16 bits that some key has: most points (the ground, the
 * buildings) belong to no box, and one bit tells most of them so without a search. */
#define OWN_FILTER_BITS 65536

RLS_EXPORT void rls_own_points(const own_points_t *a) {
    memset(a->first, 0, (size_t)(a->keys + 1) * sizeof(int64_t));
    uint64_t filter[OWN_FILTER_BITS / 64];
    memset(filter, 0, sizeof filter);
    for (int64_t k = 0; k < a->keys; k++) {
        uint32_t low = a->key[k] & (OWN_FILTER_BITS - 1);
        filter[low >> 6] |= (uint64_t)1 << (low & 63);
    }
    for (int64_t p = 0; p < a->n; p++) {
        const char *rec = a->base + p * a->stride;
        uint32_t id;
        uint8_t ghost;
        memcpy(&id, rec + a->off_instance, sizeof id);
        memcpy(&ghost, rec + a->off_ghost, sizeof ghost);
        int32_t g = -1;
        uint32_t low = id & (OWN_FILTER_BITS - 1);
        if (ghost == 0 && (filter[low >> 6] >> (low & 63) & 1)) {
            int64_t lo = 0, hi = a->keys;  /* the first key >= id */
            while (lo < hi) {
                int64_t mid = (lo + hi) / 2;
                if (a->key[mid] < id) lo = mid + 1; else hi = mid;
            }
            if (lo < a->keys && a->key[lo] == id) {
                g = (int32_t)lo;
                a->first[lo + 1]++;
            }
        }
        a->group[p] = g;
    }
    for (int64_t k = 0; k < a->keys; k++) a->first[k + 1] += a->first[k];
    /* each group's next slot: its start, moving on as its points are placed */
    int64_t *next = a->next;
    memcpy(next, a->first, (size_t)a->keys * sizeof(int64_t));
    for (int64_t p = 0; p < a->n; p++) {
        const int32_t g = a->group[p];
        if (g < 0) continue;
        memcpy(&a->times[next[g]++], a->base + p * a->stride + a->off_time, sizeof(double));
    }
}

/* The interface version of rls_own_points (RLS_OWN_POINTS_ABI). */
RLS_EXPORT int rls_own_points_abi(void) {
    return RLS_OWN_POINTS_ABI;
}
