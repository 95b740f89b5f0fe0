/* The Embree packet loop of RLS, in C: casts N rays through rtcIntersect16 on a few
 * threads while Python holds no lock (ctypes releases the GIL for the whole call).
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

typedef void (*isect16_fn)(const int *valid, void *scene, void *rayhit, void *args);

typedef struct {
    isect16_fn fn;
    void *scene;
    const float *org;  /* 3 floats, or 3 per ray when org_per_ray */
    int org_per_ray;
    const float *dir;  /* 3 floats per ray */
    float tfar;
    double *dist;
    int64_t *tri;
    int64_t lo, hi;    /* ray range of this worker */
} job_t;

static void *work(void *arg) {
    job_t *j = (job_t *)arg;
    union { float f[STRIDE]; uint32_t u[STRIDE]; } buf __attribute__((aligned(64)));
    int valid[K] __attribute__((aligned(64)));
    for (int64_t s = j->lo; s < j->hi; s += K) {
        int m = (int)((j->hi - s) < K ? (j->hi - s) : K);
        memset(&buf, 0, sizeof(buf));
        for (int l = 0; l < K; l++) {
            int64_t r = s + (l < m ? l : 0);
            const float *o = j->org_per_ray ? j->org + 3 * r : j->org;
            const float *d = j->dir + 3 * r;
            valid[l] = l < m ? -1 : 0;
            buf.f[ORG + l] = o[0];
            buf.f[ORG + K + l] = o[1];
            buf.f[ORG + 2 * K + l] = o[2];
            buf.f[DIR + l] = d[0];
            buf.f[DIR + K + l] = d[1];
            buf.f[DIR + 2 * K + l] = d[2];
            buf.f[TFAR + l] = j->tfar;
            buf.u[MASK + l] = INVALID;
            buf.u[PRIM + l] = INVALID;
            buf.u[GEOM + l] = INVALID;
        }
        j->fn(valid, j->scene, &buf, NULL);
        for (int l = 0; l < m; l++) {
            if (buf.u[GEOM + l] == INVALID) {
                j->dist[s + l] = INFINITY;
                j->tri[s + l] = -1;
            } else {
                j->dist[s + l] = buf.f[TFAR + l];
                j->tri[s + l] = (int64_t)buf.u[PRIM + l];
            }
        }
    }
    return NULL;
}

/* Returns 0 on success, -1 when a thread could not be started (results then partial). */
int rls_embree_cast(void *fn, void *scene, const float *org, int org_per_ray,
                    const float *dir, int64_t n, float tfar, double *dist, int64_t *tri,
                    int threads) {
    if (threads < 1) threads = 1;
    if (threads > 64) threads = 64;
    int64_t per = (n + threads - 1) / threads;
    per = (per + K - 1) / K * K;  /* whole packets per worker */
    job_t jobs[64];
    pthread_t ids[64];
    int started = 0, rc = 0;
    for (int t = 0; t < threads; t++) {
        int64_t lo = t * per, hi = lo + per < n ? lo + per : n;
        if (lo >= n) break;
        jobs[t] = (job_t){(isect16_fn)fn, scene, org, org_per_ray, dir, tfar, dist, tri, lo, hi};
        if (t == 0) continue;  /* the calling thread takes the first range */
        if (pthread_create(&ids[t], NULL, work, &jobs[t]) != 0) { rc = -1; break; }
        started = t;
    }
    if (n > 0) work(&jobs[0]);
    for (int t = 1; t <= started; t++) pthread_join(ids[t], NULL);
    return rc;
}
