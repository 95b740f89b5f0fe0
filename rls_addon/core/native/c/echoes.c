/* A footprint's echoes, in C (rls_addon/core/physics/echoes.py: resolve_numpy is the readable
 * reference this follows operation by operation, and gives the same bytes).
 *
 * rls_echo_group: per candidate beam, its samples (the centre ray, then RING ring
 * sub-rays): a beam whose samples all hit the centre's object within the echo
 * separation of its range keeps its return, as does a skipped ray; every other beam
 * (an active beam q, in candidate order) has its hit samples sorted by range (stable)
 * and cut into echoes where the gap exceeds the separation; per echo (key q * S + e,
 * e in range order) the sums of energy share * rho |cos| * T^2 / R^2, of share, of
 * energy x range, of share x range and of CARLA's intensity, over its samples in
 * sample order (as numpy's bincount adds them), its range (the energy-weighted mean, or
 * the share-weighted one without energy), the sample that sent the most (the first on
 * a tie), whether it holds the centre and whether more than one object sent it.
 *
 * rls_echo_choose: per active beam, from which echoes are detected (worked out in
 * numpy between the two: the detection curve takes logarithms and tanh, whose last
 * bits numpy's own routines decide): how many, the one reported (the strongest, the
 * last, or for dual the nearer of the strongest and the last, or of the strongest and
 * the second strongest when the strongest is the last) and dual's extra one, their
 * ranks among the detected echoes, and the surface and normal of the sample that sent
 * the most of each.
 *
 * The dot product of a normal and a direction is summed (x0 y0 + x2 y2) + x1 y1, as
 * numpy's einsum("csk,csk->cs") sums it on the project's build (tested: the reference
 * and this give the same bytes). Built without fused multiply-add; single-threaded
 * (a frame has about a thousand candidate beams). */
#include <math.h>
#include <stdint.h>

#include "rls_threads.h"

#define RLS_ECHOES_ABI 1
#define RING 6
#define S (1 + RING)

typedef struct {
    int64_t n_c;                /* candidate beams */
    const int64_t *c;           /* per candidate: its ray */
    const double *dist;         /* per ray of the frame: the centre's range */
    const uint8_t *valid;       /* per ray: the centre returns a point */
    const int32_t *surface;     /* per ray: (object, material) */
    const double *normal;       /* per ray: 3 doubles */
    const double *dir;          /* per ray: 3 doubles */
    const double *sdist;        /* per ring sub-ray (n_c x RING): range */
    const int64_t *stri;        /* per ring sub-ray: triangle hit, or -1 */
    const int32_t *ssurface;    /* per ring sub-ray: (object, material) */
    const double *snormal;      /* per ring sub-ray: 3 doubles */
    const double *sdir;         /* per ring sub-ray: 3 doubles */
    const uint8_t *skipped;     /* per ray of the frame: left as it is; or NULL */
    const double *refl;         /* per material: reflectivity */
    const double *t2;           /* per sample (n_c x S): two-way transmission; or NULL (1) */
    const double *ex;           /* per sample: exp(-attenuation x range); or NULL (none) */
    double rmin, rmax, sep, centre_share, ring_share;
    int64_t *beam;              /* out, per active beam: its candidate (room for n_c) */
    double *E, *R, *CA;         /* out, per key (room for n_c x S) */
    int64_t *dom;               /* out, per key: q * S + s of the sample that sent the most */
    uint8_t *has, *centre, *mixed;   /* out, per key */
} group_t;

typedef struct {
    int64_t m;                  /* active beams */
    int mode;                   /* 0 strongest, 1 last, 2 dual */
    const uint8_t *det;         /* per key: detected */
    int64_t *primary, *second;  /* out, per beam: the reported echo, dual's extra one */
    uint8_t *num, *two;         /* out, per beam: detected echoes; a second row */
    uint8_t *rank_primary, *rank_second;   /* out, per beam: 1-based rank in range */
    int32_t *surface_primary, *surface_second;   /* out, per beam: 2 each */
    double *normal_primary, *normal_second;      /* out, per beam: 3 each */
} choose_t;

static int in_range(double d, const group_t *g) {
    return isfinite(d) && d >= g->rmin && d <= g->rmax;
}

/* Sample s of candidate ci: its range, surface row and normal and direction rows. */
static void sample(const group_t *g, int64_t ci, int s, double *d, const int32_t **surf,
                   const double **n, const double **dir) {
    if (s == 0) {
        int64_t i = g->c[ci];
        *d = g->dist[i];
        *surf = g->surface + 2 * i;
        *n = g->normal + 3 * i;
        *dir = g->dir + 3 * i;
    } else {
        int64_t j = ci * RING + (s - 1);
        *d = g->sdist[j];
        *surf = g->ssurface + 2 * j;
        *n = g->snormal + 3 * j;
        *dir = g->sdir + 3 * j;
    }
}

/* Groups every candidate's samples; returns the number of active beams. */
RLS_EXPORT int64_t rls_echo_group(const group_t *g) {
    int64_t m = 0;
    for (int64_t ci = 0; ci < g->n_c; ci++) {
        double d[S];
        const int32_t *surf[S];
        const double *nrm[S], *dir[S];
        int hit[S];
        for (int s = 0; s < S; s++) {
            sample(g, ci, s, &d[s], &surf[s], &nrm[s], &dir[s]);
            hit[s] = in_range(d[s], g)
                     && (s == 0 ? g->valid[g->c[ci]] != 0 : g->stri[ci * RING + s - 1] >= 0);
        }
        int agree = 1;
        for (int s = 0; s < S; s++)
            if (!hit[s] || surf[s][0] != surf[0][0] || !(fabs(d[s] - d[0]) <= g->sep))
                agree = 0;
        if (agree || (g->skipped && g->skipped[g->c[ci]])) continue;
        int64_t q = m++;
        g->beam[q] = ci;
        double r[S], energy[S], carla[S], share[S];
        for (int s = 0; s < S; s++) {
            share[s] = s == 0 ? g->centre_share : g->ring_share;
            r[s] = hit[s] ? d[s] : INFINITY;
            double dot = (nrm[s][0] * dir[s][0] + nrm[s][2] * dir[s][2]) + nrm[s][1] * dir[s][1];
            double rho_cos = g->refl[surf[s][1]] * fabs(dot);
            double rr = hit[s] ? r[s] : 1.0;
            double t2 = g->t2 ? g->t2[ci * S + s] : 1.0;
            double cv = g->ex ? rho_cos * g->ex[ci * S + s] : rho_cos;
            cv = cv < 0.0 ? 0.0 : (cv > 1.0 ? 1.0 : cv);
            energy[s] = hit[s] ? share[s] * rho_cos * t2 / (rr * rr) : 0.0;
            carla[s] = hit[s] ? share[s] * cv * t2 : 0.0;
        }
        /* stable sort by range; a gap beyond the separation starts an echo */
        int order[S];
        for (int s = 0; s < S; s++) {
            int p = s;
            while (p > 0 && r[order[p - 1]] > r[s]) {
                order[p] = order[p - 1];
                p--;
            }
            order[p] = s;
        }
        int echo_of[S], e = 0;
        for (int p = 0; p < S; p++) {
            if (p > 0 && r[order[p]] - r[order[p - 1]] > g->sep) e++;
            echo_of[order[p]] = e;
        }
        double E[S] = {0}, W[S] = {0}, RE[S] = {0}, RW[S] = {0}, CA[S] = {0}, top[S];
        int count[S] = {0}, lo[S], hi[S];
        for (int k = 0; k < S; k++) {
            top[k] = -INFINITY;
            lo[k] = INT32_MAX;
            hi[k] = -1;
        }
        for (int s = 0; s < S; s++) {
            if (!hit[s]) continue;
            int k = echo_of[s];
            E[k] += energy[s];
            W[k] += share[s];
            RE[k] += energy[s] * r[s];
            RW[k] += share[s] * r[s];
            CA[k] += carla[s];
            count[k]++;
            if (isnan(top[k]) || isnan(energy[s])) top[k] = NAN;
            else if (energy[s] > top[k]) top[k] = energy[s];
            if (surf[s][0] < lo[k]) lo[k] = surf[s][0];
            if (surf[s][0] > hi[k]) hi[k] = surf[s][0];
        }
        for (int k = 0; k < S; k++) {
            int64_t key = q * S + k;
            g->E[key] = E[k];
            g->R[key] = E[k] > 0.0 ? RE[k] / E[k] : RW[k] / (W[k] > 0.0 ? W[k] : 1.0);
            g->CA[key] = CA[k];
            g->has[key] = count[k] > 0;
            g->centre[key] = 0;
            g->mixed[key] = count[k] > 0 && lo[k] != hi[k];
            g->dom[key] = 0;
            for (int s = 0; s < S; s++)
                if (hit[s] && echo_of[s] == k && energy[s] == top[k]) {
                    g->dom[key] = q * S + s;
                    break;
                }
        }
        if (hit[0]) g->centre[q * S + echo_of[0]] = 1;
    }
    return m;
}

/* numpy's argmax: the first largest, or the first NaN. */
static int argmax(const double *v) {
    int best = 0;
    for (int s = 0; s < S; s++) {
        if (isnan(v[s])) return s;
        if (v[s] > v[best]) best = s;
    }
    return best;
}

/* The surface and normal of the sample q * S + s of the group's active beam q. */
static void source(const group_t *g, int64_t flat, int32_t *surf, double *n) {
    int64_t ci = g->beam[flat / S];
    int s = (int)(flat % S);
    double d;
    const int32_t *sf;
    const double *nr, *dr;
    sample(g, ci, s, &d, &sf, &nr, &dr);
    surf[0] = sf[0];
    surf[1] = sf[1];
    for (int k = 0; k < 3; k++) n[k] = nr[k];
}

/* Chooses the reported echoes of every active beam of ``g``. */
RLS_EXPORT void rls_echo_choose(const group_t *g, const choose_t *c) {
    for (int64_t q = 0; q < c->m; q++) {
        const uint8_t *det = c->det + q * S;
        const double *E = g->E + q * S, *R = g->R + q * S;
        double Em[S], Rm[S];
        uint8_t rank[S];
        int num = 0;
        for (int s = 0; s < S; s++) {
            Em[s] = det[s] ? E[s] : -INFINITY;
            Rm[s] = det[s] ? R[s] : -INFINITY;
            num += det[s] != 0;
            rank[s] = (uint8_t)num;
        }
        int strongest = argmax(Em), last = argmax(Rm);
        int primary = c->mode == 1 ? last : strongest, second = last, two = 0;
        if (c->mode == 2) {
            int other = last;
            if (last == strongest) {
                double v[S];
                for (int s = 0; s < S; s++) v[s] = s == strongest ? -INFINITY : Em[s];
                other = argmax(v);
            }
            two = num > 1;
            /* (not near and far: macros of the Windows headers) */
            int nearer = Rm[other] < Rm[strongest] ? other : strongest;
            int farther = nearer == strongest ? other : strongest;
            primary = two ? nearer : strongest;
            second = two ? farther : strongest;
        }
        c->primary[q] = primary;
        c->second[q] = second;
        c->num[q] = (uint8_t)num;
        c->two[q] = (uint8_t)two;
        c->rank_primary[q] = rank[primary];
        c->rank_second[q] = rank[second];
        source(g, g->dom[q * S + primary], c->surface_primary + 2 * q, c->normal_primary + 3 * q);
        source(g, g->dom[q * S + second], c->surface_second + 2 * q, c->normal_second + 3 * q);
    }
}

/* The interface version of the echo kernels (RLS_ECHOES_ABI). */
RLS_EXPORT int rls_echoes_abi(void) {
    return RLS_ECHOES_ABI;
}
