"""Background sweeps: each still LiDAR scanned over the scene with every road user
hidden (vehicles, pedestrians and cyclists, parked ones included: they are the objects
with ground truth), a few sweeps with the device's noise, dropout and ghosts. They are
what a deployed roadside unit's background holds after hours of watching the junction
come and go, and what RLS's detector learns by default (``rls detect``, ``rls study
--evaluate``); ``rls dataset`` stores them beside its frames for any detector.

Each sweep scans the same scene frame (the first of the run) with its own seed
(``sweep_seed``: derived from the LiDAR's seed and the sweep's number, never a frame's),
so the sweeps differ only by the device's noise, as successive empty sweeps of a real
unit do, and the same inputs give the same bytes. A sensor that may move has no
background (the roadside detector is for still sensors): it is named in a notice."""

import dataclasses

import numpy as np

from ..labels import ROAD_USERS, label_id
from ..output.datasets.settings import BACKGROUND_SWEEPS  # noqa: F401 (the commands' default)
from ..scene.hidden import WithoutLabels
_TAG = 0x42474E44  # "BGND": background sweeps draw from streams of their own


def sweep_seed(seed, sweep):
    """The scan seed of background sweep ``sweep`` (0, 1, ...) of a LiDAR seeded
    ``seed``: a whole number in [0, 2^63) from ``numpy.random.SeedSequence`` of (the
    seed's low and high 32 bits, a tag, the sweep), so no two sweeps and no frame share a
    stream."""
    seed, sweep = int(seed), int(sweep)
    if seed < 0 or sweep < 0:
        raise ValueError("seeds and sweep numbers are whole numbers >= 0")
    words = [seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF, _TAG, sweep]
    if seed >> 64:
        words.append(seed >> 64)
    return int(np.random.SeedSequence(words).generate_state(1, np.uint64)[0] >> np.uint64(1))


def road_user_ids(extra=()):
    """Label ids of the road users (``labels.ROAD_USERS``) and of ``extra`` labels."""
    return {label_id(n) for n in ROAD_USERS} | {label_id(n) for n in extra}


def sweep_job(job, sweep):
    """``job`` (a ``run.SensorJob``) with the seed of background sweep ``sweep``."""
    scan = dataclasses.replace(job.settings.scan, seed=sweep_seed(job.settings.scan.seed,
                                                                  sweep))
    return dataclasses.replace(job, settings=dataclasses.replace(job.settings, scan=scan))


def still_sensors(source, jobs):
    """(jobs of still sensors, names of those that may move): only still LiDARs get a
    background."""
    still = [j for j in jobs if not source.sensor_may_move(j.name)]
    return still, [j.name for j in jobs if source.sensor_may_move(j.name)]


def background_runs(source, jobs, frame, sweeps, writer_of, progress=None, labels=(),
                    **run_options):
    """([ScanRun], the source with road users hidden, notices): one run per sweep of the
    still sensors among ``jobs`` over ``source`` at scene ``frame``, every road user
    (and objects of ``labels``) hidden; ``writer_of(sweep, hidden source)`` is each
    run's writer (the hidden source names what it hid). The
    runs are made now, so existing outputs are refused before anything is scanned; the
    caller runs them (``run_all``). ``run_options`` go to every ``ScanRun``."""
    from .run import ScanRun

    still, moving = still_sensors(source, jobs)
    notices = []
    if moving:
        notices.append(f"no background sweeps for {', '.join(moving)}: it may move (a "
                       "background is for still roadside LiDARs)")
    if not still or sweeps < 1:
        return [], None, notices
    empty = WithoutLabels(source, road_user_ids(labels))
    sessions = run_options.pop("sessions", {})
    runs = [ScanRun(empty, [sweep_job(j, k) for j in still], [frame], writer=writer_of(k, empty),
                    progress=progress, sessions=sessions, **run_options)
            for k in range(sweeps)]
    return runs, empty, notices


def run_all(runs):
    """Run the background runs in turn (they share their prepared scenes); the last one
    run, or None when a run was cancelled."""
    last = None
    for run in runs:
        run.run()
        if run.cancelled:
            return None
        last = run
    return last
