"""The bounds of an (N, 3) array's columns (``native.vectors.column_bounds``: rows
folded side by side for numpy, kept for read-only arrays) and what uses them: a
prepared scene's cover of a driving sensor's origins, judged first by the farthest
corner of their box, gives what checking every origin gives."""

import numpy as np
import pytest

from rls_addon.core.native import vectors
from rls_addon.core.native.vectors import column_bounds
from rls_addon.core.world.bodies import PreparedScene


@pytest.mark.parametrize("n", [1, 5, 31, 32, 33, 1000, 115136, 115137])
def test_the_bounds_are_numpys_least_and_greatest(n):
    a = np.random.default_rng(n).normal(size=(n, 3)) * [1e3, 1.0, 1e-3]
    lo, hi = column_bounds(a)
    assert lo.tobytes() == a.min(axis=0).tobytes() and hi.tobytes() == a.max(axis=0).tobytes()
    view = np.random.default_rng(1).normal(size=(n, 6))[:, ::2]  # strided rows
    lo, hi = column_bounds(view)
    assert lo.tobytes() == view.min(axis=0).tobytes()
    assert hi.tobytes() == view.max(axis=0).tobytes()


def test_a_read_only_arrays_bounds_are_kept_and_given_as_copies(monkeypatch):
    monkeypatch.setattr(vectors, "_BOUNDS", [])
    a = np.random.default_rng(0).normal(size=(1000, 3))
    a.flags.writeable = False
    lo, hi = column_bounds(a)
    lo[:] = 99.0  # the caller's copy
    again = column_bounds(a)
    assert again[0].tobytes() == a.min(axis=0).tobytes() and vectors._BOUNDS[0][0]() is a
    b = np.random.default_rng(1).normal(size=(1000, 3))  # writeable: not kept
    column_bounds(b)
    assert all(kept() is not b for kept, _ in vectors._BOUNDS)


def _scene(centre, reach):
    s = PreparedScene.__new__(PreparedScene)
    s.centre, s.reach = np.asarray(centre, np.float64), float(reach)
    return s


@pytest.mark.parametrize("seed", range(6))
def test_the_cover_of_many_origins_is_every_origins(seed):
    """The corner of the origins' box decides only when it is covered itself; else each
    origin is looked at: the same answer as the distance of each, near the limit too
    (a diagonal drive, whose box's corner lies farther out than any origin)."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-50, 50, 3)
    along = rng.normal(size=3)
    s = np.linspace(0.0, 1.0, 20000)[:, None]
    origins = start + s * along * rng.uniform(0.5, 3.0)
    scene = _scene(rng.uniform(-50, 50, 3), 200.0)
    gaps = np.linalg.norm(origins - scene.centre, axis=1)
    lo, hi = origins.min(axis=0), origins.max(axis=0)
    corner = np.linalg.norm(np.maximum(np.abs(lo - scene.centre), np.abs(hi - scene.centre)))
    for max_range in (200.0 - gaps.max() - 1e-9, 200.0 - gaps.max() + 1e-9,
                      200.0 - corner - 1e-9, 200.0 - (gaps.max() + corner) / 2, 10.0, 190.0):
        want = bool(np.sqrt(((origins - scene.centre) ** 2).sum(axis=1)).max() + max_range
                    <= scene.reach * (1 + 1e-12))
        assert scene.covers(origins, max_range) == want


@pytest.mark.parametrize("n", [1, 31, 32, 33, 115137])
def test_a_shifted_array_is_numpys_difference_and_keeps_its_bounds(monkeypatch, n):
    """``shifted(a, c)`` (rows folded for numpy) is ``a - c`` byte for byte, read-only;
    when ``a``'s bounds are kept its bounds are kept too, and equal numpy's least and
    greatest of the difference (rounding keeps order); a whole view of it (what
    ``reshape(-1, 3)`` gives) finds them."""
    monkeypatch.setattr(vectors, "_BOUNDS", [])
    rng = np.random.default_rng(n)
    a = rng.normal(size=(n, 3)) * [1e3, 1.0, 1e-3] + [3e5, -2.0, 7.0]
    c = np.array([3e5 + 0.1, 1e-7, -1e4])
    a.flags.writeable = False
    column_bounds(a)
    got = vectors.shifted(a, c)
    assert got.tobytes() == (a - c).tobytes() and not got.flags.writeable
    kept = [k() for k, _ in vectors._BOUNDS]
    assert kept[0] is got
    again = vectors.shifted(a.reshape(-1, 3), c)  # a whole view of it: its bounds found
    assert vectors._BOUNDS[0][0]() is again and again.tobytes() == got.tobytes()
    lo, hi = column_bounds(got.reshape(-1, 3))
    assert [k() for k, _ in vectors._BOUNDS] == [again, got, a]  # found, not recomputed
    want = (a - c)
    assert np.array_equal(lo, want.min(axis=0)) and np.array_equal(hi, want.max(axis=0))


def test_a_view_of_part_of_a_kept_array_is_not_taken_for_it(monkeypatch):
    monkeypatch.setattr(vectors, "_BOUNDS", [])
    a = np.arange(300.0).reshape(100, 3)
    a.flags.writeable = False
    column_bounds(a)
    lo, hi = column_bounds(a[:50])
    assert hi.tolist() == [147.0, 148.0, 149.0]
    lo, hi = column_bounds(a[::-1])
    assert lo.tolist() == [0.0, 1.0, 2.0] and hi.tolist() == [297.0, 298.0, 299.0]


def test_kept_bounds_last_four_frames_and_keep_no_array_alive(monkeypatch):
    """A frame's boxes are worked out behind the scan, when later frames' origins (and
    the same centred) are kept already: the bounds of an array stay found while seven
    other arrays are kept after it, once each however often each is kept again; the
    cache holds no array alive (a dropped array's entry is gone with it)."""
    import gc
    import weakref

    monkeypatch.setattr(vectors, "_BOUNDS", [])
    frames = []
    for k in range(4):  # per frame: the origins and the same centred, each kept twice
        o = np.random.default_rng(k).normal(size=(100, 3))
        o.flags.writeable = False
        column_bounds(o)
        c = vectors.shifted(o, np.array([1.0, 2.0, 3.0]))
        vectors.keep_bounds(c, *column_bounds(c))
        frames.append((o, c))
    first = frames[0][0]
    calls = []
    with monkeypatch.context() as m:
        m.setattr(np, "ascontiguousarray", lambda *a, **k: calls.append(a) or a[0])
        lo, hi = column_bounds(first)  # found: not worked out again
    assert calls == [] and lo.tobytes() == first.min(axis=0).tobytes()
    assert len(vectors._BOUNDS) == vectors._KEEP == 8
    dropped = weakref.ref(frames[-1][1])
    frames.clear()
    first = o = c = None
    gc.collect()
    assert dropped() is None and all(ref() is None for ref, _ in vectors._BOUNDS)
