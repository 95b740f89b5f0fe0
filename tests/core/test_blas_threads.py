"""The scan keeps OpenBLAS on one thread and gives the previous count back."""

import numpy as np

from rls_addon.core.native import blas_threads


def test_single_threaded_restores_the_thread_count():
    before = blas_threads.threads()
    with blas_threads.single_threaded():
        assert all(n == 1 for n in blas_threads.threads())
        with blas_threads.single_threaded():  # nested: still one, and not restored early
            pass
        assert all(n == 1 for n in blas_threads.threads())
        np.ones((300, 300)) @ np.ones((300, 300))  # BLAS still works
    assert blas_threads.threads() == before


def test_restored_even_when_the_block_raises():
    before = blas_threads.threads()
    try:
        with blas_threads.single_threaded():
            raise RuntimeError("boom")
    except RuntimeError:
        pass
    assert blas_threads.threads() == before


def test_numpy_wheel_openblas_is_found():
    """numpy's Linux wheels link OpenBLAS; without finding it the limit does nothing."""
    cfg = np.show_config(mode="dicts") if "mode" in np.show_config.__code__.co_varnames else {}
    blas_name = str(cfg.get("Build Dependencies", {}).get("blas", {}).get("name", ""))
    if "openblas" in blas_name:
        assert blas_threads.threads(), "numpy links OpenBLAS but its thread controls were not found"
