/* The Embree packet loop of RLS, in C: casts N rays through rtcIntersect16 on worker
 * threads of its own, which need no Python lock.
 *
 * Rays come in float64 (origins centre-relative, unit directions) and are rounded to
 * float32 only for Embree's traversal, 16 at a time in the given trace order (rays
 * that are neighbours in that order share a packet; results go back to each ray's own
 * slot). With a plane table, every hit is then refined
 * in float64 against its triangle's plane along the original ray (what
 * rls_addon/core/raycast.py:refine_hits does in numpy), and the triangle's unit normal
 * is written out, in the same worker thread while the triangle's data is warm.
 * rls_embree_start64 returns while the workers run; rls_embree_finish collects them.
 *
 * No Embree header is needed: the caller passes the address of rtcIntersect16 from
 * the libembree4 already loaded by the embreex wheel, and the RTCRayHit16 layout
 * (offsets in 4-byte words) is the one rls_addon/core/embree_caster.py checks with a
 * probe packet before using either path.
 *
 * Built by tools/build_native.py (gcc -O2 -shared -fPIC -pthread). */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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
#define STRIDE 384
#define INVALID 0xFFFFFFFFu
/* Below this |cos| between ray and plane the float64 plane answer is ill-conditioned
 * (grazing): Embree's own distance is kept, as refine_hits does. */
#define GRAZING 1e-6

typedef void (*isect16_fn)(const int *valid, void *scene, void *rayhit, void *args);

typedef struct {
    isect16_fn fn;
    void *scene;
    const double *org;    /* 3 doubles, or 3 per ray when org_per_ray */
    int org_per_ray;
    const double *dir;    /* 3 doubles per ray */
    const int64_t *order; /* trace order (a permutation of the rays), or NULL */
    float tfar;
    const double *plane;  /* per triangle: nx, ny, nz, n.v0; or NULL (no refinement) */
    double *dist;
    int64_t *tri;
    double *normal;       /* 3 per ray, or NULL */
    int64_t lo, hi;       /* ray range of this worker */
} job_t;

static void *work(void *arg) {
    job_t *j = (job_t *)arg;
    union { float f[STRIDE]; uint32_t u[STRIDE]; } buf __attribute__((aligned(64)));
    int valid[K] __attribute__((aligned(64)));
    for (int64_t s = j->lo; s < j->hi; s += K) {
        int m = (int)((j->hi - s) < K ? (j->hi - s) : K);
        memset(&buf, 0, sizeof(buf));
        int64_t ray[K];
        for (int l = 0; l < K; l++) {
            int64_t at = s + (l < m ? l : 0);
            int64_t r = j->order ? j->order[at] : at;
            ray[l] = r;
            const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
            const double *d = j->dir + 3 * r;
            valid[l] = l < m ? -1 : 0;
            buf.f[ORG + l] = (float)o[0];
            buf.f[ORG + K + l] = (float)o[1];
            buf.f[ORG + 2 * K + l] = (float)o[2];
            buf.f[DIR + l] = (float)d[0];
            buf.f[DIR + K + l] = (float)d[1];
            buf.f[DIR + 2 * K + l] = (float)d[2];
            buf.f[TFAR + l] = j->tfar;
            buf.u[MASK + l] = INVALID;
            buf.u[PRIM + l] = INVALID;
            buf.u[GEOM + l] = INVALID;
        }
        j->fn(valid, j->scene, &buf, NULL);
        for (int l = 0; l < m; l++) {
            int64_t r = ray[l];
            double *nrm = j->normal ? j->normal + 3 * r : NULL;
            if (buf.u[GEOM + l] == INVALID) {
                j->dist[r] = INFINITY;
                j->tri[r] = -1;
                if (nrm) nrm[0] = nrm[1] = nrm[2] = 0.0;
                continue;
            }
            uint32_t p = buf.u[PRIM + l];
            double t = buf.f[TFAR + l];
            if (j->plane) {
                const double *pl = j->plane + 4 * (int64_t)p;
                const double *o = j->org_per_ray ? j->org + 3 * r : j->org;
                const double *d = j->dir + 3 * r;
                double denom = pl[0] * d[0] + pl[1] * d[1] + pl[2] * d[2];
                double exact = (pl[3] - (pl[0] * o[0] + pl[1] * o[1] + pl[2] * o[2])) / denom;
                if (isfinite(exact) && fabs(denom) > GRAZING && exact > 0) t = exact;
                if (nrm) { nrm[0] = pl[0]; nrm[1] = pl[1]; nrm[2] = pl[2]; }
            }
            j->dist[r] = t;
            j->tri[r] = (int64_t)p;
        }
    }
    return NULL;
}

#define MAX_THREADS 64

typedef struct {
    int count;
    int running[MAX_THREADS];
    pthread_t ids[MAX_THREADS];
    job_t jobs[MAX_THREADS];
} batch_t;

/* Starts casting N rays on `threads` worker threads and returns at once (the caller
 * collects with rls_embree_finish, keeping every array alive until then). A worker
 * that cannot be started runs its share here before returning. NULL when out of
 * memory (nothing was cast). */
void *rls_embree_start64(void *fn, void *scene, const double *org, int org_per_ray,
                         const double *dir, const int64_t *order, int64_t n, float tfar,
                         const double *plane, double *dist, int64_t *tri, double *normal,
                         int threads) {
    batch_t *b = (batch_t *)calloc(1, sizeof(batch_t));
    if (!b) return NULL;
    if (threads < 1) threads = 1;
    if (threads > MAX_THREADS) threads = MAX_THREADS;
    int64_t per = (n + threads - 1) / threads;
    per = (per + K - 1) / K * K;  /* whole packets per worker */
    for (int t = 0; t < threads; t++) {
        int64_t lo = t * per, hi = lo + per < n ? lo + per : n;
        if (lo >= n) break;
        b->jobs[t] = (job_t){(isect16_fn)fn, scene, org, org_per_ray, dir, order, tfar,
                             plane, dist, tri, normal, lo, hi};
        b->running[t] = pthread_create(&b->ids[t], NULL, work, &b->jobs[t]) == 0;
        if (!b->running[t]) work(&b->jobs[t]);
        b->count = t + 1;
    }
    return b;
}

/* Waits for a batch from rls_embree_start64 and frees it. */
void rls_embree_finish(void *batch) {
    batch_t *b = (batch_t *)batch;
    if (!b) return;
    for (int t = 0; t < b->count; t++)
        if (b->running[t]) pthread_join(b->ids[t], NULL);
    free(b);
}
