"""What every section of ``make bench`` shares: the log line, the best of a few
repeats, and how times and rates are printed in the report."""

import sys
import time


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def best(fn, repeat=3):
    """(best wall time in s, last result)."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def ms(s):
    return f"{s * 1000:.1f}"


def mrays(n, s):
    return f"{n / s / 1e6:.2f}"
