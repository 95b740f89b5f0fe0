"""--workers N beyond what the machine holds (its cores, its memory for a worker of this
scene) is capped, with a notice naming the cap."""

from rls_addon.core.scan import cluster


def test_workers_beyond_the_cores_are_capped(monkeypatch):
    monkeypatch.setattr(cluster, "cores", lambda: 2)
    monkeypatch.setattr(cluster, "available_memory", lambda: 64 * 1024 ** 3)
    notices = []
    assert cluster.choose_workers(64, scans=100, rays=10 ** 6, notices=notices) == 2
    assert len(notices) == 1 and "--workers 64" in notices[0] and "2" in notices[0], notices
    assert "cores" in notices[0]
    notices.clear()
    assert cluster.choose_workers(2, scans=100, rays=10 ** 6, notices=notices) == 2
    assert notices == []


def test_workers_beyond_the_memory_are_capped(monkeypatch):
    monkeypatch.setattr(cluster, "cores", lambda: 64)
    monkeypatch.setattr(cluster, "available_memory", lambda: 16 * 1024 ** 3)
    need = cluster.worker_memory(scene_bytes=400 * 1024 ** 2, rays_per_scan=200_000)
    assert need > cluster.WORKER_MEMORY_BYTES  # a bigger scene needs more
    notices = []
    n = cluster.choose_workers(48, scans=1000, rays=10 ** 8, worker_bytes=need,
                               notices=notices)
    assert n == max(1, 16 * 1024 ** 3 // need) < 48
    assert len(notices) == 1 and f"capped at {n}" in notices[0] and "memory" in notices[0]
    # auto takes the same estimate
    assert cluster.choose_workers("auto", scans=10 ** 5, rays=10 ** 10, worker_bytes=need) == n


def test_a_scheduler_decides_its_own_workers(monkeypatch):
    monkeypatch.setattr(cluster, "cores", lambda: 2)
    notices = []
    assert cluster.choose_workers(64, 10, 10, scheduler="tcp://h:8786", notices=notices) == 0
    assert notices == []
