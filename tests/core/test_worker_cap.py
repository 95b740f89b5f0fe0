"""--workers N beyond what the machine holds (its cores, its memory for a worker of this
scene) is capped, with a notice naming the cap."""

from rls_addon.core.scan import dask_run


def test_workers_beyond_the_cores_are_capped(monkeypatch):
    monkeypatch.setattr(dask_run, "cores", lambda: 2)
    monkeypatch.setattr(dask_run, "available_memory", lambda: 64 * 1024 ** 3)
    notices = []
    assert dask_run.choose_workers(64, scans=100, rays=10 ** 6, notices=notices) == 2
    assert len(notices) == 1 and "--workers 64" in notices[0] and "2" in notices[0], notices
    assert "cores" in notices[0]
    notices.clear()
    assert dask_run.choose_workers(2, scans=100, rays=10 ** 6, notices=notices) == 2
    assert notices == []


def test_workers_beyond_the_memory_are_capped(monkeypatch):
    monkeypatch.setattr(dask_run, "cores", lambda: 64)
    monkeypatch.setattr(dask_run, "available_memory", lambda: 16 * 1024 ** 3)
    need = dask_run.worker_memory(scene_bytes=400 * 1024 ** 2, rays_per_scan=200_000)
    assert need > dask_run.WORKER_MEMORY_BYTES  # a bigger scene needs more
    notices = []
    n = dask_run.choose_workers(48, scans=1000, rays=10 ** 8, worker_bytes=need,
                               notices=notices)
    assert n == max(1, 16 * 1024 ** 3 // need) < 48
    assert len(notices) == 1 and f"capped at {n}" in notices[0] and "memory" in notices[0]
    # auto takes the same estimate
    assert dask_run.choose_workers("auto", scans=10 ** 5, rays=10 ** 10, worker_bytes=need) == n


def test_a_scheduler_decides_its_own_workers(monkeypatch):
    monkeypatch.setattr(dask_run, "cores", lambda: 2)
    notices = []
    assert dask_run.choose_workers(64, 10, 10, scheduler="tcp://h:8786", notices=notices) == 0
    assert notices == []


def test_pieces_are_short_enough_for_progress_every_few_seconds():
    """Issue 31: --frames 1-1000000 on 2 workers went in 8 pieces of 125,000 frames, with
    no progress line for 10 minutes."""
    from rls_addon.core.scan.dask_run import (
        MAX_PIECES,
        PIECE_SECONDS,
        SECONDS_PER_RAY,
        SECONDS_PER_SCAN,
        piece_count,
    )

    rays_per_scan = 115_200  # a Pandar64 frame
    for scans in (40, 300, 2_000, 60_000, 1_000_000):
        n = piece_count(2, scans, scans * rays_per_scan)
        assert 1 <= n <= scans and n >= min(scans, 8)  # a few pieces a worker at least
        per_piece = scans / n * (SECONDS_PER_SCAN + rays_per_scan * SECONDS_PER_RAY)
        if n < MAX_PIECES:
            assert per_piece <= PIECE_SECONDS * 1.01
    assert piece_count(2, 10**7, 10**7 * rays_per_scan) == MAX_PIECES  # a bound on tasks
    assert piece_count(4, 3, 3 * rays_per_scan) == 3  # never more pieces than scans


def test_auto_stays_here_for_a_still_sensor_over_a_still_scene(monkeypatch):
    """Issue 31: 300 frames of one still Pandar64 over a scene where nothing moves
    started two workers (5.8 s against 5.7 s in one process): its frames reuse their
    first cast, and the model now counts them as such."""
    monkeypatch.setattr(dask_run, "cores", lambda: 2)
    monkeypatch.setattr(dask_run, "available_memory", lambda: 64 * 1024 ** 3)
    rays = 115_200
    still = dask_run.run_seconds([(300, rays, True)])
    moving = dask_run.run_seconds([(300, rays, False)])
    assert still < 5 < dask_run.AUTO_MIN_SECONDS < moving
    assert dask_run.choose_workers("auto", 300, 300 * rays, estimate=still) == 1
    assert dask_run.choose_workers("auto", 300, 300 * rays, estimate=moving) == 2
    # the default is the full model, as before
    assert dask_run.choose_workers("auto", 300, 300 * rays) == 2
    assert dask_run.run_seconds([(300, rays, True), (300, rays, False)]) == \
        still + moving


def test_still_sensors_are_those_that_cannot_move_in_a_timeless_scene():
    from rls_addon.core.scan.run import ScanRun, SensorJob
    from rls_addon.core.scan.settings import LidarSettings

    from .fakes import numpy_factory, small_preset, street

    scene, still_scene = street(), [True]
    scene.timeless = lambda: still_scene[0]
    scene.sensor_may_move = lambda sensor: sensor == "car"
    jobs = [SensorJob(n, LidarSettings(), small_preset()) for n in ("pole", "car")]
    run = ScanRun(scene, jobs, [1, 2], factory=numpy_factory)
    assert run.still_sensors() == {"pole"}
    still_scene[0] = False
    assert run.still_sensors() == set()
    del scene.timeless  # a source that cannot tell: none are counted still
    assert run.still_sensors() == set()
