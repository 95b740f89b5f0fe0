/* A track's positions at many times, in C (rls_track_positions): a moving sensor's
 * origin at the firing time of each of its rays (115,136 a Pandar64 frame, every
 * channel at its own time).
 *
 * rls_addon/core/scene/motion.py (Track.positions_at: _segments, then hermite) is the
 * readable reference this follows operation by operation: the knot interval of each
 * time (the last knot at or before it, clamped to the first and the last interval),
 * the fraction along it (clamped to [0, 1]; an interval of no length divides by 1), and
 * cubic Hermite with the knots' velocities, its four terms summed left to right as
 * numpy sums them; the library is built without fused multiply-add, so both give the
 * same bits. A row whose time is the row above's (to the bit: the channels of a
 * firing share it) copies that row's position, the same bits without the arithmetic.
 * Times are split into shares on a few threads.
 *
 * With `centre` the positions come back centred on it too (`centred`, each position
 * minus the centre: native/vectors.py's shifted, the same bits), in the same pass: a
 * frame's rays are cast from origins centred on its prepared scene.
 *
 * With `bounds` the least and greatest of each column of the output come back too
 * (lo x y z, hi x y z: what native/vectors.py's column_bounds gives for it), found in
 * the same pass; `nan` is set when a position is not a number (the caller then asks
 * numpy, whose min and max a NaN wins). */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "rls_shares.h"

#define RLS_TRACKS_ABI 3

typedef struct {
    int64_t knots;          /* K >= 2 */
    const double *times;    /* K, increasing */
    const double *position; /* K x 3 */
    const double *velocity; /* K x 3 */
    int64_t n;
    const double *t;        /* n query times */
    double *out;            /* n x 3 */
    double *bounds;         /* 6 (lo xyz, hi xyz) or NULL */
    int32_t nan;            /* out: 1 when a position is NaN (bounds not given) */
    const double *centre;   /* 3, or NULL */
    double *centred;        /* n x 3: out - centre (with centre) */
} positions_t;

typedef struct {
    const positions_t *a;
    int64_t lo, hi;
    double bounds[6];
    int nan;
} share_t;

/* The same time to the bit (not ==, which takes -0.0 for 0.0): the same position. */
static int same_bits(double a, double b) {
    uint64_t x, y;
    memcpy(&x, &a, sizeof x);
    memcpy(&y, &b, sizeof y);
    return x == y;
}

/* numpy's searchsorted(times, t, side="right") - 1, clipped to [0, K - 2]. */
static int64_t segment(const double *times, int64_t k, double t) {
    if (t != t) return k - 2;  /* NaN sorts last */
    int64_t lo = 0, hi = k;    /* the first knot after t, by bisection */
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (times[mid] <= t) lo = mid + 1;
        else hi = mid;
    }
    int64_t i = lo - 1;
    return i < 0 ? 0 : (i > k - 2 ? k - 2 : i);
}

static void run_share(void *arg) {
    share_t *s = (share_t *)arg;
    const positions_t *a = s->a;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int nan = 0;
    for (int64_t r = s->lo; r < s->hi; r++) {
        double t = a->t[r];
        if (r > s->lo && same_bits(t, a->t[r - 1])) {  /* fired together: the row above */
            for (int k = 0; k < 3; k++) a->out[3 * r + k] = a->out[3 * r - 3 + k];
            if (a->centre)
                for (int k = 0; k < 3; k++) a->centred[3 * r + k] = a->centred[3 * r - 3 + k];
            continue;
        }
        int64_t i = segment(a->times, a->knots, t);
        double span = a->times[i + 1] - a->times[i];
        double f = (t - a->times[i]) / (span > 0 ? span : 1.0);
        f = f < 0.0 ? 0.0 : (f > 1.0 ? 1.0 : f);  /* np.clip: a NaN stays NaN */
        double f2 = f * f, f3 = f * f * f;
        double h00 = 2 * f3 - 3 * f2 + 1, h10 = (f3 - 2 * f2 + f) * span;
        double h01 = 3 * f2 - 2 * f3, h11 = (f3 - f2) * span;
        const double *p0 = a->position + 3 * i, *p1 = p0 + 3;
        const double *v0 = a->velocity + 3 * i, *v1 = v0 + 3;
        for (int k = 0; k < 3; k++) {
            double x = h00 * p0[k] + h10 * v0[k] + h01 * p1[k] + h11 * v1[k];
            a->out[3 * r + k] = x;
            if (a->centre) a->centred[3 * r + k] = x - a->centre[k];
            lo[k] = x < lo[k] ? x : lo[k];
            hi[k] = x > hi[k] ? x : hi[k];
            nan |= x != x;
        }
    }
    for (int k = 0; k < 3; k++) {
        s->bounds[k] = lo[k];
        s->bounds[3 + k] = hi[k];
    }
    s->nan = nan;
}

/* Below this many times per share a thread costs more than it saves. */
#define MIN_SHARE 32768

RLS_EXPORT void rls_track_positions(positions_t *a, int threads) {
    int shares = rls_share_count(a->n, threads, MIN_SHARE);
    share_t s[RLS_MAX_SHARES];
    for (int k = 0; k < shares; k++) {
        s[k] = (share_t){a, 0, 0, {0}, 0};
        rls_share_bounds(a->n, shares, k, &s[k].lo, &s[k].hi);
    }
    rls_run_shares(run_share, s, sizeof(share_t), shares);
    if (a->bounds == NULL) return;
    double *b = a->bounds;
    int nan = 0;
    for (int k = 0; k < 3; k++) {
        b[k] = INFINITY;
        b[3 + k] = -INFINITY;
    }
    for (int j = 0; j < shares; j++) {
        nan |= s[j].nan;
        for (int k = 0; k < 3; k++) {
            b[k] = s[j].bounds[k] < b[k] ? s[j].bounds[k] : b[k];
            b[3 + k] = s[j].bounds[3 + k] > b[3 + k] ? s[j].bounds[3 + k] : b[3 + k];
        }
    }
    a->nan = nan;
}

/* The interface version of rls_track_positions (RLS_TRACKS_ABI). */
RLS_EXPORT int rls_tracks_abi(void) {
    return RLS_TRACKS_ABI;
}
