/* Work on a range of items split into shares, run on threads of their own and the
 * caller's (the per-hit stage, the depth-edge test and the weather's false returns).
 *
 *     rls_share_count(n, threads, min_share)   how many shares n items make
 *     rls_share_bounds(n, shares, k, &lo, &hi) share k's items [lo, hi)
 *     rls_run_shares(fn, shares, size, count)  fn on each share, all at once
 *
 * The shares split the items into equal runs in order (the last one shorter), so a
 * kernel that writes share by share from each share's first item on can move the
 * shares' output together afterwards and keep the items' order. */
#ifndef RLS_SHARES_H
#define RLS_SHARES_H

#include <stddef.h>
#include <stdint.h>

#include "rls_threads.h"

#define RLS_MAX_SHARES 64

/* One share per thread (at least one, at most RLS_MAX_SHARES), but none smaller than
 * min_share items: below that a thread costs more than it saves. */
static int rls_share_count(int64_t n, int threads, int64_t min_share) {
    int shares = threads < 1 ? 1 : (threads > RLS_MAX_SHARES ? RLS_MAX_SHARES : threads);
    if (shares > 1 && n / shares < min_share) shares = (int)(n / min_share) + 1;
    return shares > RLS_MAX_SHARES ? RLS_MAX_SHARES : shares;
}

/* Share k of n items in `shares` equal runs: [*lo, *hi). */
static void rls_share_bounds(int64_t n, int shares, int k, int64_t *lo, int64_t *hi) {
    int64_t step = (n + shares - 1) / shares;
    *lo = k * step < n ? k * step : n;
    *hi = *lo + step < n ? *lo + step : n;
}

typedef void (*rls_share_fn)(void *share);

typedef struct {
    rls_share_fn fn;
    void *share;
} rls_share_call_t;

RLS_THREAD_ENTRY(rls_share_entry, arg) {
    rls_share_call_t *c = (rls_share_call_t *)arg;
    c->fn(c->share);
    RLS_THREAD_RETURN;
}

/* Runs fn on `count` shares laid out `size` bytes apart from `shares`: share 0 in the
 * caller while the others run on threads of their own; a share whose thread cannot be
 * started runs in the caller afterwards. Returns when every share is done. */
static void rls_run_shares(rls_share_fn fn, void *shares, size_t size, int count) {
    rls_share_call_t calls[RLS_MAX_SHARES];
    rls_thread ids[RLS_MAX_SHARES];
    int started[RLS_MAX_SHARES] = {0};
    if (count > RLS_MAX_SHARES) count = RLS_MAX_SHARES;
    for (int k = 1; k < count; k++) {
        calls[k] = (rls_share_call_t){fn, (char *)shares + (size_t)k * size};
        started[k] = rls_thread_start(&ids[k], rls_share_entry, &calls[k]);
    }
    fn(shares);
    for (int k = 1; k < count; k++) {
        if (started[k]) rls_thread_join(ids[k]);
        else fn((char *)shares + (size_t)k * size);
    }
}

#endif /* RLS_SHARES_H */
