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
import shutil
import tempfile

from ..errors import RLSError, SettingsError

# Below this estimated serial time a local cluster costs more than it saves.
AUTO_MIN_SECONDS = 20.0
# What a worker holds: the bpy module, one open scene, prepared ray-casting structures.
WORKER_MEMORY_BYTES = 2 * 1024 ** 3
# A worker of a bigger scene (``worker_memory``), an estimate: the scene's meshes in
# Blender and again in the casting structures, several times the .blend's size; a
# scan's arrays per ray (directions, hits, draws, the point records).
SCENE_MEMORY_FACTOR = 8
BYTES_PER_RAY = 400
# A rough serial cost model for ``auto``: per scan and per ray (Embree, one core)
SECONDS_PER_SCAN = 0.05
SECONDS_PER_RAY = 2.5e-7
# Checked against bench/scale_out.py, 2026-11-22 23:27 to 11-23 00:02 (2 cores, load
# average 1.2-2.5 from the benchmark itself, other work under 0.05 cores; the sample
# intersection with 6 LiDARs, `rls dataset --layout kitti --frames 1-60`): its 360 scans
# of 28.6 M rays took 26.3-34.2 s in one process (the machine's speed drifts), 513-680
# ns per ray in scan_frame and 32-41 ms per scan for the rest (frame changes, ground
# truth, files); the model says 25.2 s, so the constants stay. Two workers were
# 1.49-1.74x faster, with fixed costs of 2.7-3.8 s (0.8-1.2 s in one process): break-even
# at about 4-6 s of serial work, 1.3x at 10-15 s, so AUTO_MIN_SECONDS = 20 s starts
# workers where they clearly pay. The model overestimates a study's scans 4-5x (840
# scans of 96.8 M rays, no files, no frame changes: 12.3-15.3 s; the model says 66 s;
# two workers 1.17-1.19x faster): no pair of these two constants fits both, and scan
# runs are the ones that lose most when ``auto`` wrongly stays in one process.


# A still sensor over a scene where nothing changes casts its frame once and reuses it
# (``ScanRun.still_sensors``): its later frames cost their points, not their rays.
# Measured 2026-11-25 on the 2-core machine (bench/long_runs.py and `rls scan` of 300
# frames, the sample intersection without its traffic): a VLP-16 frame (28,928 rays)
# 3.0 ms, a Pandar64 frame (115,200 rays) 10.7 ms, both with their files; a line through
# the two. The full model put the Pandar64's 300 frames at 24 s and started two
# workers: 5.7 s in one process, 5.8 s on two.
STILL_SECONDS_PER_SCAN = 0.0005
STILL_SECONDS_PER_RAY = 9e-8


def model_seconds(scans, rays):
    """The cost model's serial seconds of ``scans`` scans of ``rays`` rays in all,
    none of them still."""
    return scans * SECONDS_PER_SCAN + rays * SECONDS_PER_RAY


def run_seconds(sensors):
    """The cost model's serial seconds of a run: ``sensors`` [(scans, rays per scan,
    still)], ``still`` for a sensor whose frames reuse their first cast."""
    total = 0.0
    for scans, rays, still in sensors:
        if still:
            total += rays * SECONDS_PER_RAY + scans * (STILL_SECONDS_PER_SCAN
                                                       + rays * STILL_SECONDS_PER_RAY)
        else:
            total += scans * (SECONDS_PER_SCAN + rays * SECONDS_PER_RAY)
    return total


# Pieces: at least a few per worker (balance), and short enough that progress comes every
# few seconds: a run of 1,000,000 frames in 8 pieces of 125,000 frames said nothing for
# 10 minutes. A worker keeps its open scene and prepared structures over all the pieces
# it gets, so a piece costs its rays and a scheduler round trip (milliseconds).
PIECES_PER_WORKER = 4
PIECE_SECONDS = 5.0
MAX_PIECES = 20_000


def piece_count(workers, scans, rays, estimate=None):
    """How many pieces a run of ``scans`` scans (``rays`` rays in all; or ``estimate``
    seconds, ``run_seconds``) on ``workers`` workers is split into:
    ``PIECES_PER_WORKER`` each at least, more when the cost model says a piece would
    take longer than ``PIECE_SECONDS``, never more than the scans or ``MAX_PIECES``."""
    if estimate is None:
        estimate = model_seconds(scans, rays)
    n = max(workers * PIECES_PER_WORKER, math.ceil(estimate / PIECE_SECONDS))
    return int(max(1, min(n, MAX_PIECES, scans)))


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


def worker_memory(scene_bytes=0, rays_per_scan=0):
    """An estimate of one worker's memory for a scene of ``scene_bytes`` (its .blend)
    scanned ``rays_per_scan`` rays at a time: at least ``WORKER_MEMORY_BYTES``."""
    return int(WORKER_MEMORY_BYTES + SCENE_MEMORY_FACTOR * max(0, scene_bytes)
               + BYTES_PER_RAY * max(0, rays_per_scan))


def machine_cap(worker_bytes=WORKER_MEMORY_BYTES):
    """The most local workers this machine holds, and why: one per core, and no more
    than its free memory holds workers of ``worker_bytes``."""
    n, why = cores(), f"this machine has {cores()} cores"
    mem = available_memory()
    if mem is not None and mem // worker_bytes < n:
        n = max(1, int(mem // worker_bytes))
        why = (f"its {mem / 1024 ** 3:.1f} GB of free memory hold {n} worker(s) of about "
               f"{worker_bytes / 1024 ** 3:.1f} GB for this scene")
    return n, why


def choose_workers(requested, scans, rays, scheduler=None, local_ok=True,
                   worker_bytes=WORKER_MEMORY_BYTES, notices=None, estimate=None):
    """How many workers a run gets: 1 means in-process (today's run). With a scheduler
    address the cluster decides (returns 0: 'whatever the scheduler has'). A number
    beyond this machine's cores or memory (``machine_cap``, workers of ``worker_bytes``)
    is capped, and a notice naming the cap is added to ``notices``. ``auto`` starts
    workers when the run's serial seconds (``estimate``, ``run_seconds``; default: of
    ``scans`` and ``rays`` with nothing still) reach ``AUTO_MIN_SECONDS``."""
    if scheduler:
        return 0
    if requested != "auto":
        n = int(requested)
        cap, why = machine_cap(worker_bytes)
        if n > cap:
            if notices is not None:
                notices.append(f"--workers {n}: capped at {cap} ({why})")
            n = cap
        return n
    n = cores()
    if not local_ok or n < 2:
        return 1
    if estimate is None:
        estimate = model_seconds(scans, rays)
    if estimate < AUTO_MIN_SECONDS or scans < 2 * n:
        return 1
    return int(machine_cap(worker_bytes)[0])


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
    env = {"RLS_THREADS": str(threads or threads_per_worker(workers)),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    # Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536 (its
    # ``distributed.nanny.pre-spawn-environ``). Setting it also fixes glibc's mmap
    # threshold at 128 KiB, so every large numpy array of a scan is mapped and unmapped
    # anew and its pages faulted in again: the time goes to the kernel. Measured
    # 2026-11-22 on the 2-core machine, bench/scale_out.py's dataset (360 scans, 6
    # LiDARs, 60 frames): one process 60.1 s with the variable set, 30.8 s without;
    # two workers 33.8 s with it (slower than one process without it), 22.4 s without.
    # Workers keep glibc's defaults, as a run in one process has them (a variable set
    # in this process's environment still reaches them).
    import dask

    from ..stop_signals import held

    # Blender keeps a session folder in the temporary directory (``bpy.app.tempdir``)
    # and removes it when its process ends normally; a nanny ends its worker process
    # without that, which left an empty ``blender_*`` folder in the system's temporary
    # directory per worker per run. The workers' temporary directory is this cluster's
    # own, removed once the cluster has closed (or the run is stopped).
    env["TMPDIR"] = scratch = tempfile.mkdtemp(prefix="rls-workers-")
    cluster = client = None
    try:
        # a stop signal waits for the cluster to be up (cut mid-start, its nannies
        # were left half-started), then the cluster is closed as at any other stop
        with held():
            with dask.config.set({"distributed.nanny.pre-spawn-environ"
                                  ".MALLOC_TRIM_THRESHOLD_": None}):
                cluster = distributed.LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True,
                    host="127.0.0.1", dashboard_address=None, silence_logs=50,
                    worker_class=distributed.Nanny, env=env)
            client = distributed.Client(cluster)
        yield client
    finally:
        with held():
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
            shutil.rmtree(scratch, ignore_errors=True)


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
