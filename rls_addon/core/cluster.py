"""Runs spread over the cores of a machine or over a cluster, on Dask distributed.

Dask is imported only here and only when a run asks for workers, with a clear error
when it is missing: Blender's UI never needs it (its operators run in-process).

    workers = choose_workers("auto", scans=480, rays=55_000_000)
    with cluster_client(workers, scheduler=None) as client:   # LocalCluster, or a
        for result in as_completed_results(client, futures):  # scheduler address
            ...

``auto`` runs in-process when the run is too small to pay for starting workers
(each imports Blender and opens the scene: a few seconds), else one worker per core,
capped by memory. Embree's threads per worker are set so that workers x threads stays
within the cores.
"""

import contextlib
import math
import os

from .errors import RLSError, SettingsError

# Below this estimated serial time a local cluster costs more than it saves.
AUTO_MIN_SECONDS = 20.0
# What a worker holds: the bpy module, one open scene, prepared ray-casting structures.
WORKER_MEMORY_BYTES = 2 * 1024 ** 3
# A rough serial cost model for ``auto``: per scan and per ray (Embree, one core)
SECONDS_PER_SCAN = 0.05
SECONDS_PER_RAY = 2.5e-7


class ClusterError(RLSError):
    """The cluster cannot be started or reached, or a worker's task failed."""


def cores():
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def available_memory():
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except ImportError:
        return None


def parse_workers(text):
    """'auto' or a positive integer from ``--workers``."""
    if text is None or str(text).strip().lower() == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        raise SettingsError(f"--workers takes a number of workers or 'auto', got {text!r}") \
            from None
    if n < 1:
        raise SettingsError(f"--workers must be at least 1, got {n}")
    return n


def choose_workers(requested, scans, rays, scheduler=None, local_ok=True):
    """How many workers a run gets: 1 means in-process (today's run). With a scheduler
    address the cluster decides (returns 0: 'whatever the scheduler has')."""
    if scheduler:
        return 0
    if requested != "auto":
        return int(requested)
    n = cores()
    if not local_ok or n < 2:
        return 1
    estimate = scans * SECONDS_PER_SCAN + rays * SECONDS_PER_RAY
    if estimate < AUTO_MIN_SECONDS or scans < 2 * n:
        return 1
    mem = available_memory()
    if mem is not None:
        n = max(1, min(n, mem // WORKER_MEMORY_BYTES))
    return int(n)


def threads_per_worker(workers):
    """Embree threads for each of ``workers`` local workers (all of a remote machine's
    cores when the scheduler is remote: 0)."""
    if workers <= 0:
        return 0
    return max(1, cores() // workers)


def _distributed():
    try:
        import distributed
    except ImportError:
        raise ClusterError("runs over several workers need Dask: pip install "
                           "'dask[distributed]' (or run with --workers 1)") from None
    return distributed


@contextlib.contextmanager
def cluster_client(workers, scheduler=None, threads=None):
    """A Dask client: to the scheduler at ``scheduler``, or to a new LocalCluster of
    ``workers`` worker processes on the loopback address (closed afterwards)."""
    distributed = _distributed()
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout="30s")
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            yield client
        finally:
            client.close()
        return
    env = {"RLS_EMBREE_THREADS": str(threads or threads_per_worker(workers)),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    cluster = distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, silence_logs=50, worker_class=distributed.Nanny,
        env=env)
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def run_tasks(client, calls, on_result, key_prefix="rls"):
    """Submit ``calls`` [(function, args tuple)] and call ``on_result(index, result)`` as
    each finishes. A task whose worker dies is run again elsewhere by Dask (its
    ``allowed-failures``); the first task that raises ends the run: the others are
    cancelled and the error is raised here."""
    distributed = _distributed()
    futures = {}
    for i, (fn, args) in enumerate(calls):
        fut = client.submit(fn, *args, key=f"{key_prefix}-{i}-{os.getpid()}-{id(calls)}",
                            pure=False, retries=0)
        futures[fut] = i
    try:
        for fut in distributed.as_completed(list(futures)):
            i = futures[fut]
            if fut.status == "error":
                exc = fut.exception()
                raise exc if isinstance(exc, RLSError) else ClusterError(
                    f"a worker's task failed: {type(exc).__name__}: {exc}")
            on_result(i, fut.result())
    except BaseException:
        client.cancel(list(futures))
        raise


def shards(items, pieces):
    """``items`` in at most ``pieces`` contiguous runs of near-equal length."""
    items = list(items)
    if not items:
        return []
    pieces = max(1, min(int(pieces), len(items)))
    size = math.ceil(len(items) / pieces)
    return [items[i:i + size] for i in range(0, len(items), size)]
