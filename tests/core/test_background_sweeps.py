"""Background sweeps (``scan/background_sweeps.py``): each still sensor scanned over the
scene with every road user hidden, a few sweeps each with its own seed."""

import numpy as np

from rls_addon.core.scan.background_sweeps import background_runs, run_all, sweep_seed
from rls_addon.core.scan.run import SensorJob
from rls_addon.core.scan.settings import LidarSettings, ScanSettings
from rls_addon.core.scene.hidden import WithoutLabels

from .fakes import numpy_factory, small_preset, street


def test_sweep_seeds_are_their_own_streams_and_stable():
    seeds = [sweep_seed(s, k) for s in (0, 1, 2**40 + 3) for k in range(5)]
    assert len(set(seeds)) == len(seeds)  # no two sweeps share a stream
    assert all(0 <= s < 2**63 for s in seeds)
    assert sweep_seed(7, 2) == sweep_seed(7, 2)
    assert sweep_seed(0, 0) not in range(0, 1000)  # never a small seed a frame may use


class Kept:
    """A writer keeping what it is given (``run.Writer``)."""

    def __init__(self):
        self.points = {}

    path = planned_files = incomplete = lambda self, *a: []  # noqa: E731

    def check(self, *a):
        pass

    def existing(self, *a, **k):
        return None

    def write(self, sensor, output, frame, points, info):
        self.points[sensor] = points
        return f"{sensor}-{frame}"

    def finish(self, run):
        pass

    def abort(self):
        pass

    flush = abort


def test_sweeps_hide_road_users_and_differ_only_by_noise():
    scene = street()  # a ground slab, a wall, a parked car (a vehicle) by the sensors
    scene.moving_sensors = ("mast",)
    jobs = [SensorJob(n, LidarSettings(scan=ScanSettings(seed=3)), small_preset(noise=0.02))
            for n in ("pole", "mast")]
    writers = []

    def writer_of(k, hidden):
        writers.append(Kept())
        return writers[-1]

    runs, hidden, notices = background_runs(scene, jobs, 2, 3, writer_of,
                                            factory=numpy_factory)
    assert len(runs) == 3 and notices == ["no background sweeps for mast: it may move (a "
                                          "background is for still roadside LiDARs)"]
    run_all(runs)
    assert hidden.hidden == {"car"} and isinstance(hidden, WithoutLabels)
    assert all(set(w.points) == {"pole"} for w in writers)
    sweeps = [w.points["pole"] for w in writers]
    assert all(run.frames == [2] for run in runs)
    # the car is gone: nothing is returned from where it stood
    xyz = [np.stack([p["x"], p["y"], p["z"]], 1) for p in sweeps]
    in_car = [((x[:, 0] > 1.7) & (x[:, 0] < 6.3) & (x[:, 1] > -9.0) & (x[:, 1] < -7.0)
               & (x[:, 2] > -0.8)).sum() for x in xyz]
    assert in_car == [0, 0, 0]
    # the same rays, other noise
    assert len({len(p) for p in sweeps}) == 1
    assert not np.array_equal(sweeps[0]["x"], sweeps[1]["x"])
    ranges = [np.linalg.norm(x, axis=1) for x in xyz]
    assert 0.005 < np.std(ranges[0] - ranges[1]) < 0.05  # two draws of 2 cm noise
    # again: the same bytes
    again = []
    runs, _, _ = background_runs(scene, jobs, 2, 3,
                                 lambda k, h: again.append(Kept()) or again[-1],
                                 factory=numpy_factory)
    run_all(runs)
    assert all(a.points["pole"].tobytes() == w.points["pole"].tobytes()
               for a, w in zip(again, writers))
