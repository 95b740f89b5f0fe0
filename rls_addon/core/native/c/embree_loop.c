/* The Embree packet loop of RLS, in C: casts N rays through rtcIntersect16 on worker
 * threads of its own and the caller's (see rls_embree_launch), which need no Python
 * lock.
 *
 * Rays come in float64 (origins centre-relative, unit directions) and are rounded to
 * float32 only for Embree's traversal, 16 at a time in the given trace order (rays
 * that are neighbours in that order share a packet; results go back to each ray's own
 * slot). With a plane table, every hit is then refined
 * in float64 against its triangle's plane along the original ray (what
 * rls_addon/core/casting/base.py:refine_hits does in numpy), and the triangle's unit normal
 * is written out, in the same worker thread while the triangle's data is warm.
 * Rays may carry a scene time (for instances with motion time steps); then the
 * instance each hit lies in is written out too. With an instance table, instance i's
 * triangles have their own plane table (planes_of[i], or NULL: not refined) and a hit
 * on an instance placed by time steps (info[2i+1] > 0 steps of 12 doubles, a 3x4
 * row-major matrix each, from step info[2i]) is refined in that instance's own
 * coordinates, with its matrix interpolated linearly at the ray's time exactly as
 * Embree does (the normal goes back to world by the inverse transpose).
 * rls_embree_launch returns while the workers run; rls_embree_finish joins in and
 * collects them.
 *
 * No Embree header is needed: the caller passes the address of rtcIntersect16 from
 * the libembree4 already loaded by the embreex wheel, and the RTCRayHit16 layout
 * (offsets in 4-byte words) is the one rls_addon/core/casting/embree.py checks with a
 * probe packet before using either path.
 *
 * Built by tools/build_native.py for every platform the extension ships on (zig cc
 * cross-compiles: Linux, Windows, macOS; gcc or cc for this machine alone), with
 * -ffp-contract=off so that no target fuses a multiply and an add: every platform
 * refines to the same float64 bits. Threads come from rls_threads.h (Win32 or
 * POSIX), the shared ray counter is a C11 atomic; GCC or Clang (the aligned and
 * prefetch attributes). */
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rls_threads.h"

/* What rls_embree_abi returns: the loader (embree.py, _native_loop) refuses a build
 * that answers anything else, or lacks the function (a build older than the
 * arguments it passes). Bump it whenever an exported signature or meaning changes. */
#define RLS_EMBREE_ABI 4

#define K 16
#define ORG 0
#define TNEAR 48
#define DIR 64
#define TIME 112
#define TFAR 128
#define MASK 144
#define ID 160
#define FLAGS 176
#define PRIM 272
#define GEOM 288
#define INST 304
#define STRIDE 384
#define INVALID 0xFFFFFFFFu
/* Below this |cos| between ray and plane the float64 plane answer is ill-conditioned
 * (grazing): Embree's own distance is kept, as refine_hits does. */
#define GRAZING 1e-6

typedef void (*isect16_fn)(const int *valid, void *scene, void *rayhit, void *args);

/* The watertight re-check of misses, done in the worker threads (what
 * rls_addon/core/casting/watertight.py: WatertightCaster._recheck does in numpy, the
 * reference this follows operation by operation, so both give the same bits):
 * a miss that cannot reach any hull box (one box per octant of directions, the union
 * of the boxes ahead of the origins) is a real miss; the
 * others are cast into the hull (padded boxes of triangle clusters), and those that
 * enter a box are cast once more with the origin nudged perpendicular to the ray; a
 * nudged hit counts when the original ray crosses that triangle within tol. */
typedef struct {
    void *hull;            /* the hull's Embree scene */
    const double *boxes;   /* 8 x (lo xyz, hi xyz), or NULL (no prefilter) */
    const int32_t *has;    /* 8: the octant has a box */
    double max_dist;
    const double *vertices;   /* V x 3, the scene's */
    const int64_t *triangles; /* T x 3 */
    double tol;
    double nudge;
    double axis[3];
    /* An instanced job (static_inst >= 0): the static scene is instance static_inst,
     * and after its hits are refined, the rays that did not hit it (misses, and rays
     * that hit a moving instance) are re-checked against the static scene alone
     * (instancing.py: InstancedWorld._finish, the reference): the nudged rays go into
     * the static scene's own build (scene), a hit won back is refined against its
     * plane (planes) and kept where it is nearer than the ray's moving hit (a moving
     * hit beyond max_dist counts as none); with use_limit, a ray whose first hull box
     * lies beyond its moving hit is not re-checked. */
    void *scene;
    const double *planes;
    int32_t static_inst;
    int32_t use_limit;
    _Atomic int64_t retried;  /* out: rays re-cast nudged */
} recheck_t;

typedef struct {
    isect16_fn fn;
    void *scene;
    const double *org;    /* 3 doubles, or 3 per ray when org_per_ray */
    int org_per_ray;
    const double *dir;    /* 3 doubles per ray */
    const int64_t *order; /* trace order (a permutation of the rays), or NULL */
    float tfar;
    const float *time;    /* per ray, in [0, 1], or NULL (time 0) */
    int32_t *inst;        /* per ray: instance of the hit (-1: miss, or no instance), or NULL */
    const double *steps;  /* instance matrices, 12 doubles each, or NULL */
    const int64_t *info;  /* per instance: first step, step count (0: identity) */
    const double *const *planes_of;  /* per instance: its plane table, or NULL */
    int n_inst;
    const double *plane;  /* per triangle: nx, ny, nz, n.v0; or NULL (no refinement) */
    double *dist;
    int64_t *tri;
    double *normal;       /* 3 per ray, or NULL */
    recheck_t *recheck;   /* the watertight re-check of misses, or NULL */
    int64_t n;            /* rays */
    _Atomic int64_t *next;  /* shared: the first ray no worker has taken yet */
} job_t;

/* Workers take rays in blocks of this many from a shared counter (not in fixed
 * shares), so a worker that the system preempts, or that meets costlier rays, does
 * not hold up the others. */
#define BLOCK (32 * K)

/* The instance's matrix at time tau (steps interpolated linearly, as Embree does),
 * the ray carried into the instance's coordinates (ol, dl: dl not unit, so a ray
 * parameter there is the world range), and the unit world normal of plane pl. */
static void local_ray(const double *m, int64_t nsteps, double tau, const double *o,
                      const double *d, const double *pl, double *ol, double *dl,
                      double *nw) {
    double a[12];
    if (nsteps == 1) {
        memcpy(a, m, sizeof(a));
    } else {
        double ft = (tau < 0 ? 0 : tau > 1 ? 1 : tau) * (double)(nsteps - 1);
        int64_t i = (int64_t)floor(ft);
        if (i > nsteps - 2) i = nsteps - 2;
        double f = ft - (double)i;
        const double *m0 = m + 12 * i, *m1 = m0 + 12;
        for (int k = 0; k < 12; k++) a[k] = (1.0 - f) * m0[k] + f * m1[k];
    }
    /* inverse of the 3x3 part (rows a[0..2], a[4..6], a[8..10]) by cofactors */
    double c00 = a[5] * a[10] - a[6] * a[9], c01 = a[6] * a[8] - a[4] * a[10],
           c02 = a[4] * a[9] - a[5] * a[8];
    double c10 = a[2] * a[9] - a[1] * a[10], c11 = a[0] * a[10] - a[2] * a[8],
           c12 = a[1] * a[8] - a[0] * a[9];
    double c20 = a[1] * a[6] - a[2] * a[5], c21 = a[2] * a[4] - a[0] * a[6],
           c22 = a[0] * a[5] - a[1] * a[4];
    double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    double inv[9] = {c00 / det, c10 / det, c20 / det,
                     c01 / det, c11 / det, c21 / det,
                     c02 / det, c12 / det, c22 / det};
    double q[3] = {o[0] - a[3], o[1] - a[7], o[2] - a[11]};
    for (int k = 0; k < 3; k++) {
        ol[k] = inv[3 * k] * q[0] + inv[3 * k + 1] * q[1] + inv[3 * k + 2] * q[2];
        dl[k] = inv[3 * k] * d[0] + inv[3 * k + 1] * d[1] + inv[3 * k + 2] * d[2];
    }
    /* world normal: inverse transpose, inv^T n */
    double len = 0;
    for (int k = 0; k < 3; k++) {
        nw[k] = inv[k] * pl[0] + inv[3 + k] * pl[1] + inv[6 + k] * pl[2];
        len += nw[k] * nw[k];
    }
    len = sqrt(len);
    if (len > 0) for (int k = 0; k < 3; k++) nw[k] /= len;
}

static double dot3(const double *a, const double *b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double *a, const double *b, double *out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static void unit3(double *v) {
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[0] /= len;
    v[1] /= len;
    v[2] /= len;
}

/* False when the ray surely meets no hull box within max_dist (watertight.py:
 * may_reach_hull). */
static int may_reach_hull(const recheck_t *rc, const double *o, const double *d) {
    int code = (d[0] < 0) | ((d[1] < 0) << 1) | ((d[2] < 0) << 2);
    if (!rc->has[code]) return 0;
    const double *box = rc->boxes + 6 * code;
    double lo[3] = {box[0] - o[0], box[1] - o[1], box[2] - o[2]};
    double hi[3] = {box[3] - o[0], box[4] - o[1], box[5] - o[2]};
    double t_in = -INFINITY, t_out = INFINITY;
    for (int k = 0; k < 3; k++) {
        double t1, t2;
        if (d[k] == 0) {
            int inside = lo[k] <= 0 && hi[k] >= 0;
            t1 = inside ? -INFINITY : INFINITY;
            t2 = inside ? INFINITY : -INFINITY;
        } else {
            double inv = 1.0 / d[k];
            t1 = lo[k] * inv;
            t2 = hi[k] * inv;
        }
        double a = t1 < t2 ? t1 : t2, b = t1 < t2 ? t2 : t1;
        if (a > t_in) t_in = a;
        if (b < t_out) t_out = b;
    }
    return t_in <= t_out && t_out >= 0 && t_in <= rc->max_dist;
}

/* How far the ray's crossing of triangle p's plane lies outside the triangle
 * (watertight.py: outside_distance). */
static double outside_distance(const recheck_t *rc, int64_t p, const double *o,
                               const double *d) {
    const int64_t *t = rc->triangles + 3 * p;
    const double *a = rc->vertices + 3 * t[0], *b = rc->vertices + 3 * t[1],
                 *c = rc->vertices + 3 * t[2];
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3];
    cross3(ab, ac, n);
    unit3(n);
    double denom = dot3(n, d);
    double ao[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]};
    double s = dot3(n, ao) / denom;
    double x[3] = {o[0] + d[0] * s, o[1] + d[1] * s, o[2] + d[2] * s};
    double out = 0.0;
    const double *ps[3] = {a, b, c}, *qs[3] = {b, c, a};
    for (int e = 0; e < 3; e++) {
        const double *pp = ps[e], *q = qs[e];
        double pq[3] = {q[0] - pp[0], q[1] - pp[1], q[2] - pp[2]};
        double m[3];
        cross3(n, pq, m);
        unit3(m);
        double xp[3] = {x[0] - pp[0], x[1] - pp[1], x[2] - pp[2]};
        double v = -dot3(xp, m);
        /* np.maximum: NaN wins */
        out = (isnan(out) || isnan(v)) ? NAN : (v > out ? v : out);
    }
    return (isfinite(out) && s > 0) ? out : INFINITY;
}

/* Fills lane l of a packet with a float64 ray rounded to float32. */
static void put_ray(float *f, uint32_t *u, int l, const double *o, const double *d, float tfar,
                    float time) {
    f[ORG + l] = (float)o[0];
    f[ORG + K + l] = (float)o[1];
    f[ORG + 2 * K + l] = (float)o[2];
    f[DIR + l] = (float)d[0];
    f[DIR + K + l] = (float)d[1];
    f[DIR + 2 * K + l] = (float)d[2];
    f[TNEAR + l] = 0.0f;
    f[TIME + l] = time;
    f[TFAR + l] = tfar;
    u[MASK + l] = INVALID;
    u[ID + l] = 0;
    u[FLAGS + l] = 0;
    u[PRIM + l] = INVALID;
    u[GEOM + l] = INVALID;
    u[INST + l] = INVALID;
}

/* The re-check of the misses of one cast packet (buf), in place: a miss won back
 * gets the nudged cast's triangle and distance (refined afterwards like any hit). */
static void recheck_packet(job_t *j, float *bf, uint32_t *bu, const int64_t *ray, int m) {
    recheck_t *rc = j->recheck;
    union { float f[STRIDE]; uint32_t u[STRIDE]; } hb __attribute__((aligned(64)));
    int valid[K] __attribute__((aligned(64)));
    int any = 0;
    for (int l = 0; l < K; l++) {
        valid[l] = 0;
        if (l >= m || bu[GEOM + l] != INVALID) continue;
        int64_t r = ray[l];
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        if (rc->boxes && !may_reach_hull(rc, o, d)) continue;
        put_ray(hb.f, hb.u, l, o, d, j->tfar, 0.0f);
        valid[l] = -1;
        any = 1;
    }
    if (!any) return;
    j->fn(valid, rc->hull, &hb, NULL);
    double nudged[K][3];
    any = 0;
    for (int l = 0; l < K; l++) {
        if (!valid[l]) continue;
        if (hb.u[GEOM + l] == INVALID) {
            valid[l] = 0;
            continue;
        }
        int64_t r = ray[l];
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        double perp[3];
        cross3(d, rc->axis, perp);
        unit3(perp);
        for (int k = 0; k < 3; k++) nudged[l][k] = o[k] + perp[k] * rc->nudge;
        put_ray(hb.f, hb.u, l, nudged[l], d, j->tfar, 0.0f);
        any++;
    }
    if (!any) return;
    atomic_fetch_add_explicit(&rc->retried, any, memory_order_relaxed);
    j->fn(valid, j->scene, &hb, NULL);
    for (int l = 0; l < K; l++) {
        if (!valid[l] || hb.u[GEOM + l] == INVALID) continue;
        int64_t r = ray[l];
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        uint32_t p = hb.u[PRIM + l];
        if (outside_distance(rc, (int64_t)p, o, d) <= rc->tol) {
            bu[GEOM + l] = hb.u[GEOM + l];
            bu[PRIM + l] = p;
            bf[TFAR + l] = hb.f[TFAR + l];
        }
    }
}

/* The moving hit a static crack must be nearer than: the ray's refined hit on a
 * moving instance within max_dist, else none. */
static double moving_limit(const job_t *j, int64_t r) {
    return (j->inst[r] >= 0 && j->dist[r] <= j->recheck->max_dist) ? j->dist[r] : INFINITY;
}

/* The re-check of an instanced job's packet, after its hits are refined (see
 * recheck_t): what WatertightCaster._recheck and refine_hits do in numpy for
 * InstancedWorld._finish, operation by operation. */
static void recheck_instanced(job_t *j, const int64_t *ray, int m) {
    recheck_t *rc = j->recheck;
    union { float f[STRIDE]; uint32_t u[STRIDE]; } hb __attribute__((aligned(64)));
    int valid[K] __attribute__((aligned(64)));
    double limit[K];
    int any = 0;
    for (int l = 0; l < K; l++) {
        valid[l] = 0;
        if (l >= m) continue;
        int64_t r = ray[l];
        if (j->inst[r] == rc->static_inst) continue;  /* a static hit stands */
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        if (rc->boxes && !may_reach_hull(rc, o, d)) continue;
        limit[l] = moving_limit(j, r);
        put_ray(hb.f, hb.u, l, o, d, j->tfar, 0.0f);
        valid[l] = -1;
        any = 1;
    }
    if (!any) return;
    j->fn(valid, rc->hull, &hb, NULL);
    any = 0;
    for (int l = 0; l < K; l++) {
        if (!valid[l]) continue;
        if (hb.u[GEOM + l] == INVALID
            || (rc->use_limit && !((double)hb.f[TFAR + l] <= limit[l]))) {
            valid[l] = 0;
            continue;
        }
        int64_t r = ray[l];
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        double perp[3], nudged[3];
        cross3(d, rc->axis, perp);
        unit3(perp);
        for (int k = 0; k < 3; k++) nudged[k] = o[k] + perp[k] * rc->nudge;
        put_ray(hb.f, hb.u, l, nudged, d, j->tfar, 0.0f);
        any++;
    }
    if (!any) return;
    atomic_fetch_add_explicit(&rc->retried, any, memory_order_relaxed);
    j->fn(valid, rc->scene, &hb, NULL);
    for (int l = 0; l < K; l++) {
        if (!valid[l] || hb.u[GEOM + l] == INVALID) continue;
        int64_t r = ray[l];
        const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
        const double *d = j->dir + 3 * r;
        uint32_t p = hb.u[PRIM + l];
        if (!(outside_distance(rc, (int64_t)p, o, d) <= rc->tol)) continue;
        const double *pl = rc->planes + 4 * (int64_t)p;
        double t = hb.f[TFAR + l];
        double denom = pl[0] * d[0] + pl[1] * d[1] + pl[2] * d[2];
        double exact = (pl[3] - (pl[0] * o[0] + pl[1] * o[1] + pl[2] * o[2])) / denom;
        if (isfinite(exact) && fabs(denom) > GRAZING && exact > 0) t = exact;
        if (t < moving_limit(j, r)) {
            j->dist[r] = t;
            j->tri[r] = (int64_t)p;
            j->inst[r] = rc->static_inst;
            if (j->normal) memcpy(j->normal + 3 * r, pl, 3 * sizeof(double));
        }
    }
}

/* Casts rays [lo, hi) packet by packet. */
static void cast_range(job_t *j, int64_t lo, int64_t hi) {
    union { float f[STRIDE]; uint32_t u[STRIDE]; } buf __attribute__((aligned(64)));
    int valid[K] __attribute__((aligned(64)));
    for (int64_t s = lo; s < hi; s += K) {
        int m = (int)((hi - s) < K ? (hi - s) : K);
        int64_t ray[K];
        for (int l = 0; l < K; l++) {
            int64_t at = s + (l < m ? l : 0);
            int64_t r = j->order ? j->order[at] : at;
            ray[l] = r;
            const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
            const double *d = j->dir + 3 * r;
            valid[l] = l < m ? -1 : 0;
            put_ray(buf.f, buf.u, l, o, d, j->tfar, j->time ? j->time[r] : 0.0f);
        }
        j->fn(valid, j->scene, &buf, NULL);
        if (j->recheck && j->recheck->static_inst < 0) recheck_packet(j, buf.f, buf.u, ray, m);
        if (j->plane && !j->info)  /* fetch the hit triangles' planes together */
            for (int l = 0; l < m; l++)
                if (buf.u[GEOM + l] != INVALID)
                    __builtin_prefetch(j->plane + 4 * (int64_t)buf.u[PRIM + l]);
        for (int l = 0; l < m; l++) {
            int64_t r = ray[l];
            double *nrm = j->normal ? j->normal + 3 * r : NULL;
            if (buf.u[GEOM + l] == INVALID) {
                j->dist[r] = INFINITY;
                j->tri[r] = -1;
                if (j->inst) j->inst[r] = -1;
                if (nrm) nrm[0] = nrm[1] = nrm[2] = 0.0;
                continue;
            }
            uint32_t p = buf.u[PRIM + l];
            double t = buf.f[TFAR + l];
            int32_t in = buf.u[INST + l] == INVALID ? -1 : (int32_t)buf.u[INST + l];
            if (j->inst) j->inst[r] = in;
            const double *planes = j->plane;
            int64_t nsteps = 0;
            if (j->info) {
                planes = in >= 0 && in < j->n_inst ? j->planes_of[in] : NULL;
                nsteps = planes ? j->info[2 * in + 1] : 0;
                if (!planes && nrm) nrm[0] = nrm[1] = nrm[2] = 0.0;
            }
            if (planes) {
                /* The ray in the triangle's own coordinates (the world's, unless the
                 * instance moves) and the triangle's world normal. */
                const double *pl = planes + 4 * (int64_t)p;
                const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
                const double *d = j->dir + 3 * r;
                double ol[3], dl[3], nw[3], len = 1.0;
                if (nsteps > 0) {
                    double tau = j->time ? j->time[r] : 0.0;
                    local_ray(j->steps + 12 * j->info[2 * in], nsteps, tau, o, d, pl, ol, dl, nw);
                    len = sqrt(dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2]);
                } else {
                    memcpy(ol, o, sizeof(ol));
                    memcpy(dl, d, sizeof(dl));
                    memcpy(nw, pl, sizeof(nw));
                }
                double denom = pl[0] * dl[0] + pl[1] * dl[1] + pl[2] * dl[2];
                double exact = (pl[3] - (pl[0] * ol[0] + pl[1] * ol[1] + pl[2] * ol[2])) / denom;
                if (isfinite(exact) && fabs(denom) > GRAZING * len && exact > 0) t = exact;
                if (nrm) memcpy(nrm, nw, sizeof(nw));
            }
            j->dist[r] = t;
            j->tri[r] = (int64_t)p;
        }
        if (j->recheck && j->recheck->static_inst >= 0 && j->inst) recheck_instanced(j, ray, m);
    }
}

static void work(job_t *j) {
    for (;;) {
        int64_t lo = atomic_fetch_add_explicit(j->next, BLOCK, memory_order_relaxed);
        if (lo >= j->n) break;
        cast_range(j, lo, lo + BLOCK < j->n ? lo + BLOCK : j->n);
    }
}

RLS_THREAD_ENTRY(worker, arg) {
    work((job_t *)arg);
    RLS_THREAD_RETURN;
}

#define MAX_THREADS 64

typedef struct {
    job_t job;     /* one job: the threads share its ray counter (see BLOCK) */
    _Atomic int64_t next;
    int workers;
    rls_thread ids[MAX_THREADS];
} batch_t;

/* Starts casting N rays with `threads` threads, counting the caller's: threads - 1
 * workers start now, and the caller joins in when it collects the batch with
 * rls_embree_finish (keeping every array alive until then). So the caller's own work
 * between the two calls overlaps the cast without taking a core from it, and
 * threads = 1 casts in the caller alone, at rls_embree_finish. A worker that cannot be
 * started leaves its share to the others. NULL when out of memory (nothing was cast). */
RLS_EXPORT void *rls_embree_launch(void *fn, void *scene, const double *org, int org_per_ray,
                        const double *dir, const int64_t *order, int64_t n, float tfar,
                        const float *time, int32_t *inst, const double *steps,
                        const int64_t *info, const double *const *planes_of, int n_inst,
                        const double *plane,
                        double *dist, int64_t *tri, double *normal, int threads,
                        recheck_t *recheck) {
    batch_t *b = (batch_t *)calloc(1, sizeof(batch_t));
    if (!b) return NULL;
    b->job = (job_t){(isect16_fn)fn, scene, org, org_per_ray, dir, order, tfar, time, inst,
                     steps, info, planes_of, n_inst, plane, dist, tri, normal, recheck, n,
                     &b->next};
    atomic_init(&b->next, 0);
    int64_t blocks = (n + BLOCK - 1) / BLOCK;
    int want = threads - 1;
    if (want > MAX_THREADS) want = MAX_THREADS;
    if (want > blocks - 1) want = (int)(blocks - 1);  /* the caller takes one block */
    for (int t = 0; t < want; t++)
        if (rls_thread_start(&b->ids[b->workers], worker, &b->job)) b->workers++;
    return b;
}

/* Casts what the workers have not taken yet, waits for them, and frees the batch. */
RLS_EXPORT void rls_embree_finish(void *batch) {
    batch_t *b = (batch_t *)batch;
    if (!b) return;
    work(&b->job);
    for (int t = 0; t < b->workers; t++) rls_thread_join(b->ids[t]);
    free(b);
}

/* The interface version of this build (RLS_EMBREE_ABI). */
RLS_EXPORT int rls_embree_abi(void) {
    return RLS_EMBREE_ABI;
}
