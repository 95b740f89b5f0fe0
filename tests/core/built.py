"""The compiled kernels the core tests compare with their numpy references must be
built (``make test`` builds them): a missing one fails, it is not skipped."""

import pytest


def require_built(*kernels):
    """The bound functions of ``kernels`` (``core.kernels.Kernel``); fails the test with
    each one's reason when any is not built."""
    missing = [k for k in kernels if k.get() is None]
    if missing:
        pytest.fail("not built: " + "; ".join(f"{k.name} ({k.error})" for k in missing)
                    + ": run 'make native' (make test does)")
    return tuple(k.get() for k in kernels)


def both_ways(monkeypatch, module, fn, *args):
    """``fn(*args)`` with ``module.compiled`` on, then off: (the compiled kernel's
    answer, the numpy reference's)."""
    got = fn(*args)
    monkeypatch.setattr(module, "compiled", False)
    want = fn(*args)
    monkeypatch.setattr(module, "compiled", True)
    return got, want
