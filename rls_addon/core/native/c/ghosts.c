/* Ghost points from glossy surfaces, in C: the two steps around a frame's bounce cast
 * (rls_addon/core/physics/ghost.py: aim_numpy and land_numpy are the readable references this
 * follows operation by operation, so both give the same bits).
 *
 * rls_ghost_aim, before the cast: per ray, a valid return on a glossy surface (its
 * material is glossy, or its object is) whose ghost uniform is below its material's
 * ghost ratio sends a beam on; written out are the ray, its range a to the mirror, the
 * reflected direction r = u - (2 (u.n)) n, the mirror point p = o + u a and the
 * reflected beam's start, p lifted off the surface towards the side the beam came from
 * by 1e-6 + 4e-6 a.
 *
 * rls_ghost_land, after it: a reflected beam that found a surface at b (measured again
 * from the mirror point: |start + r b - p|) within the sensor's range in total
 * (a + b <= rmax) turns its ray into a ghost at range a + b with the second surface's
 * normal; the others return nothing. The surfaces' ids are the caller's (they depend
 * on the world's bodies).
 *
 * Dot products and squared lengths are summed left to right, ((x0 y0 + x1 y1) + x2 y2),
 * as the references spell them out. Built without fused multiply-add. One pass over
 * the rays, single-threaded (a frame's 115k rays in a fraction of a millisecond). */
#include <math.h>
#include <stdint.h>

#include "rls_threads.h"

#define RLS_GHOSTS_ABI 1

static double dot3(const double *x, const double *y) {
    return (x[0] * y[0] + x[1] * y[1]) + x[2] * y[2];
}

typedef struct {
    int64_t n;                  /* rays */
    const uint8_t *valid;       /* per ray: it returned a point within range */
    const int32_t *surface;     /* n x 2: (object, material) of what it hit */
    const uint8_t *obj_glossy;  /* per object, or NULL: no object is glossy */
    int64_t n_obj;
    const uint8_t *mat_glossy;  /* per material */
    const double *mat_ratio;    /* per material: the share of glossy returns that bounce */
    int64_t n_mat;
    const double *uniforms;     /* per ray, the ghost generator's */
    const double *dist;         /* per ray: range */
    const double *dirs;         /* n x 3 unit directions */
    const double *normals;      /* n x 3 unit normals of what was hit */
    const double *origins;      /* 1 or n rows of 3 */
    int64_t per_ray_origins;
    int64_t glossy_hits;        /* out: valid returns on glossy surfaces */
    int64_t *chosen;            /* out, room for n: the rays that bounce */
    double *a, *r, *p, *start;  /* out, room for n (r, p, start: rows of 3) */
} aim_t;

/* Returns how many rays bounce, or -1 when a surface id is out of its table (nothing
 * meaningful written then). */
RLS_EXPORT int64_t rls_ghost_aim(aim_t *g) {
    int64_t m = 0, hits = 0;
    for (int64_t i = 0; i < g->n; i++) {
        if (!g->valid[i]) continue;
        int32_t obj = g->surface[2 * i], mat = g->surface[2 * i + 1];
        if (mat < 0 || mat >= g->n_mat) return -1;
        int glossy = g->mat_glossy[mat] != 0;
        if (g->obj_glossy) {
            if (obj < 0 || obj >= g->n_obj) return -1;
            glossy |= g->obj_glossy[obj] != 0;
        }
        if (!glossy) continue;
        hits++;
        if (!(g->uniforms[i] < g->mat_ratio[mat])) continue;
        const double *u = g->dirs + 3 * i, *nr = g->normals + 3 * i;
        const double *o = g->origins + (g->per_ray_origins ? 3 * i : 0);
        double a = g->dist[i], d = dot3(u, nr), t = 2.0 * d;
        double eps = 1e-6 + 4e-6 * a;
        double *r = g->r + 3 * m, *p = g->p + 3 * m, *s = g->start + 3 * m;
        for (int k = 0; k < 3; k++) {
            r[k] = u[k] - t * nr[k];
            p[k] = o[k] + u[k] * a;
            s[k] = p[k] + (d < 0 ? nr[k] : -nr[k]) * eps;
        }
        g->chosen[m] = i;
        g->a[m] = a;
        m++;
    }
    g->glossy_hits = hits;
    return m;
}

typedef struct {
    int64_t m;                  /* bounced rays (rls_ghost_aim's) */
    const int64_t *chosen;
    const double *a, *r, *p, *start;
    const double *b;            /* per bounce: range of the reflected beam's hit */
    const int64_t *tri;         /* per bounce: the triangle it hit, or < 0 */
    const double *n2;           /* per bounce: that surface's unit normal (rows of 3) */
    double rmax;
    uint8_t *valid;             /* per ray, updated: a bounce that found nothing clears it */
    double *dist;               /* per ray, updated: a ghost's total path */
    double *normals;            /* per ray (rows of 3), updated: a ghost's second surface */
    uint8_t *ghost;             /* per ray, zeroed by the caller: set on ghosts */
    const int32_t *surface;     /* n x 2, read: the mirror's material */
    const double *reflectivity; /* per material */
    int64_t n_mat;
    int64_t *found;             /* out, room for m: the bounces that became ghosts */
    double *last_leg;           /* out, room for m rows of 3: their reflected directions */
    double *mirror;             /* out, room for m: their mirror's reflectivity */
} land_t;

/* Returns how many ghosts, or -1 when a mirror's material is out of its table. */
RLS_EXPORT int64_t rls_ghost_land(land_t *g) {
    int64_t count = 0;
    for (int64_t k = 0; k < g->m; k++) {
        int64_t i = g->chosen[k];
        if (g->tri[k] >= 0) {
            const double *s = g->start + 3 * k, *r = g->r + 3 * k, *p = g->p + 3 * k;
            double bk = g->b[k], x[3];
            for (int j = 0; j < 3; j++) x[j] = (s[j] + r[j] * bk) - p[j];
            double b = sqrt(dot3(x, x)), total = g->a[k] + b;
            if (total <= g->rmax) {
                int32_t mat = g->surface[2 * i + 1];
                if (mat < 0 || mat >= g->n_mat) return -1;
                g->found[count] = k;
                g->mirror[count] = g->reflectivity[mat];
                for (int j = 0; j < 3; j++) {
                    g->last_leg[3 * count + j] = r[j];
                    g->normals[3 * i + j] = g->n2[3 * k + j];
                }
                g->dist[i] = total;
                g->ghost[i] = 1;
                count++;
                continue;
            }
        }
        g->valid[i] = 0;
    }
    return count;
}

/* The interface version of rls_ghost_aim and rls_ghost_land (RLS_GHOSTS_ABI). */
RLS_EXPORT int rls_ghosts_abi(void) {
    return RLS_GHOSTS_ABI;
}
