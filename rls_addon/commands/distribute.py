"""``--workers`` and ``--scheduler``: ``rls scan``, ``rls dataset`` and ``rls study`` on
every core of a machine or on a Dask cluster.

A scan run is split into pieces (per sensor, runs of consecutive frames; per frame
range with every sensor for layouts whose files need a whole frame), a study into
blocks of candidates. Workers (``commands/worker.py``) open the .blend once and keep it;
pieces come back in any order and the run takes them in plan order, so files, the
summary and the study's tables are what one process writes (seeds come from
(seed, sensor, frame)). A worker killed mid-piece loses nothing: Dask runs the piece
again elsewhere, and it keeps the frames the first attempt finished.
"""

import os
import sys
import time

from ..core.scan.dask_run import (
    ClusterError,
    choose_workers,
    cluster_client,
    parse_workers,
    piece_count,
    run_seconds,
    run_tasks,
    shards,
    worker_memory,
)
from ..core.errors import SceneError


def add_arguments(p):
    g = p.add_argument_group("scale out (Dask)")
    g.add_argument("--workers", default="auto", metavar="N|auto",
                   help="worker processes: 1 runs here; N starts a local Dask cluster of N; "
                        "auto (default) runs here when the run is small, else one worker "
                        "per core (capped by memory)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="an existing Dask scheduler (tcp://host:8786): its workers need "
                        "the bpy wheel, this package and the scene on a shared path")


def scene_file(args):
    """The .blend the workers open: the one named, else the one Blender has open."""
    if args.blend:
        return os.path.abspath(args.blend)
    from ..blender import bpy

    if bpy.data.filepath:
        return bpy.data.filepath
    raise SceneError("workers open the scene from its file: save it, or name the .blend")


def _local_cluster_possible():
    """A local cluster starts Python processes of this interpreter that import the bpy
    module: not from inside the Blender program (its Python has no bpy module)."""
    try:
        from ..blender import bpy

        return not bpy.app.binary_path or os.path.basename(sys.executable).startswith("python")
    except ImportError:
        return False


def worker_count(args, scans, rays, blend=None, estimate=None):
    """The workers of a run of ``scans`` scans of ``rays`` rays in all (``estimate``:
    its serial seconds, if known better), of the scene in ``blend``: what --workers
    asks, capped at what this machine holds (a notice)."""
    requested = parse_workers(args.workers)
    local_ok = _local_cluster_possible()
    if requested != "auto" and requested > 1 and not args.scheduler and not local_ok:
        raise ClusterError("a local cluster needs the bpy module (python -m rls_addon ...); "
                           "from the Blender program use --workers 1 or --scheduler ADDRESS")
    try:
        scene_bytes = os.path.getsize(blend) if blend else 0
    except OSError:
        scene_bytes = 0
    notices = []
    n = choose_workers(requested, scans, rays, args.scheduler, local_ok,
                       worker_memory(scene_bytes, rays // max(1, scans)), notices, estimate)
    for notice in notices:
        print(f"rls: notice: {notice}", file=sys.stderr, flush=True)
    return n


def _eta(done, total, t0):
    if not done:
        return 0.0
    return (time.perf_counter() - t0) / done * (total - done)


def run_scan(args, run, blend, by_sensor=True):
    """Run ``run`` (a ``core.run.ScanRun``) here or over workers, as ``--workers`` and
    ``--scheduler`` say; returns it, complete."""
    per_scan = {j.name: len(j.preset.pattern(run.frames[0])) for j in run.sensors}
    rays = sum(per_scan.values()) * len(run.frames)
    still = run.still_sensors()
    estimate = run_seconds([(len(run.frames), per_scan[n], n in still) for n in per_scan])
    workers = worker_count(args, run.total, rays, blend, estimate)
    if workers != 1 and not run.writer.shardable:
        if args.scheduler or parse_workers(args.workers) != "auto":
            print("rls: notice: a ROS 2 bag is written by one process: running here",
                  file=sys.stderr)
        workers = 1
    if workers == 1:
        return run.run()
    writer = run.writer  # existing files were refused when the run was made (ScanRun)
    # A piece run again after its worker died keeps what the first attempt finished.
    writer.resume = not writer.overwrite
    t0 = time.perf_counter()
    from .worker import scan_piece

    jobs = {j.name: j for j in run.sensors}
    notices, said = [], set()
    try:
        with cluster_client(workers, args.scheduler) as client:
            size = max(1, len(client.scheduler_info().get("workers", {})) or workers)
            pieces = run.pieces(piece_count(size, run.total, rays, estimate), by_sensor)
            print(f"rls: {len(pieces)} pieces on {size} Dask worker(s)"
                  + (f" at {args.scheduler}" if args.scheduler else " (local cluster)"),
                  file=sys.stderr, flush=True)

            def absorb(i, got):
                run.absorb(got.steps, got.id_map, got.warnings)
                notices.extend(n for n in got.notices if n not in notices)
                names, frames = pieces[i]
                pts = sum(s.points for s in got.steps)
                print(f"[{run.index}/{run.total}] {', '.join(names)} frames {frames[0]}-{frames[-1]} "
                      f"({got.worker}): {pts} points, about {_eta(run.index, run.total, t0):.1f} s "
                      "left", file=sys.stderr, flush=True)
                for w in (w for s in got.steps for w in s.warnings):  # as a serial run says
                    if w not in said:  # them, each once
                        said.add(w)
                        print(f"rls: warning: {w}", file=sys.stderr)

            run_tasks(client, [(scan_piece, (blend, [jobs[n] for n in names], frames, writer,
                                             args.prepare_blender))
                               for names, frames in pieces], absorb)
    finally:
        # Once the cluster is closed: a local cluster's workers are stopped then, so a
        # write still under way on one of them cannot leave a sidecar after its cloud
        # was removed here
        remove_temporaries(run)
    if hasattr(writer, "notices"):
        writer.notices[:] = notices + [n for n in writer.notices if n not in notices]
    return run


def remove_temporaries(run):
    """What killed workers left beside this run's outputs (``ScanRun.remove_leftovers``:
    temporaries of writes in progress, clouds without their sidecar); a later --resume
    scans those again."""
    run.remove_leftovers()


def study_scan_all(args, blend):
    """A ``run_study(scan_all=...)`` that hands blocks of candidates to workers, or None
    to scan here (``--workers`` / ``--scheduler``). Workers send back counts only
    (``CandidateScan``); the few candidates a density map needs are scanned again here
    by ``run_study``'s own scanner, built from the same scene and settings (the same
    seeds: the same points)."""
    from .worker import study_piece

    def scan_all(scanner, cands, on_scan):
        rays = len(scanner.preset.pattern(scanner.frame)) * len(cands) \
            * (1 + len(scanner.traffic))
        workers = worker_count(args, len(cands) * (1 + len(scanner.traffic)), rays, blend)
        if workers == 1:
            for c in cands:
                on_scan(scanner.scan(c))
            return
        with cluster_client(workers, args.scheduler) as client:
            size = max(1, len(client.scheduler_info().get("workers", {})) or workers)
            blocks = shards([c.index for c in cands],
                            piece_count(size, len(cands) * (1 + len(scanner.traffic)), rays))
            print(f"rls: {len(blocks)} candidate blocks on {size} Dask worker(s)",
                  file=sys.stderr, flush=True)
            run_tasks(client, [(study_piece, (blend, scanner.cfg, b, args.prepare_blender)) for b in blocks],
                      lambda i, scans: [on_scan(s) for s in scans])

    return scan_all
