"""Live coverage without Blender (``core/live``): the scheduler's debounce, supersede
and budget driven with a fake clock and scanner, as Blender's timer would call it, and
the per-LiDAR coverage against ``infra_lob_metrics`` on all clouds."""

import dataclasses

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.live.coverage import Coverage, cells, level_colours, levels
from rls_addon.core.live.schedule import LIVE, ON_DEMAND, LiveScheduler, LiveSettings
from rls_addon.core.metrics.infra import infra_lob_metrics
from rls_addon.core.points import empty_points
from rls_addon.core.scan.kept_sweeps import KeptSweeps
from rls_addon.core.scan.session import ScanSession
from rls_addon.core.scan.settings import ScanSettings

from .fakes import small_preset, street, translation


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


class Scanner:
    """Scans take ``cost`` seconds of the fake clock; ``during`` runs inside a scan."""

    def __init__(self, clock, cost=0.01, publish_cost=0.005):
        self.clock, self.cost, self.publish_cost = clock, cost, publish_cost
        self.scanned, self.shown, self.during = [], [], None
        self.state = {}  # key -> its pose now (what a scan sees)

    def scan(self, key):
        self.scanned.append(key)
        if self.during:
            self.during(key)
        self.clock.t += self.cost
        return (key, self.state.get(key))

    def publish(self, ready):
        self.clock.t += self.publish_cost
        self.shown.append(dict(ready))


def run_timer(sched, clock, horizon=10.0):
    """Call ``tick`` when it asks to be called, as ``bpy.app.timers`` would, until it is
    idle (or ``horizon`` seconds pass)."""
    end = clock.t + horizon
    while clock.t < end:
        wait = sched.tick()
        if wait is None:
            return
        clock.t += wait


def drag(sched, scanner, clock, key, steps, every):
    """Move LiDAR ``key`` in ``steps`` steps ``every`` seconds apart, the timer running
    in between (a drag in the viewport)."""
    for i in range(steps):
        scanner.state[key] = i
        sched.changed([key])
        until = clock.t + every
        while clock.t < until:
            wait = sched.tick()
            clock.t = until if wait is None else min(until, clock.t + max(wait, 1e-4))


def test_a_drag_costs_one_scan_after_it_settles():
    clock = Clock()
    scanner = Scanner(clock)
    sched = LiveScheduler(scanner, clock, LiveSettings(debounce_s=0.05))
    drag(sched, scanner, clock, "LiDAR", 20, 0.016)  # 20 steps at 60 Hz
    assert scanner.scanned == []  # nothing while it moves
    last_move = clock.t - 0.016
    run_timer(sched, clock)
    assert scanner.scanned == ["LiDAR"] and sched.scans == 1 and sched.superseded == 0
    assert scanner.shown == [{"LiDAR": ("LiDAR", 19)}]  # the last pose
    (update,) = sched.updates
    assert update.scans == 1 and update.keys == ("LiDAR",)
    # shown the debounce plus the scan and the showing after the last move
    assert update.latency_s == pytest.approx(0.05 + 0.01 + 0.005, abs=1e-3)
    assert clock.t - last_move == pytest.approx(update.latency_s, abs=1e-3)


def test_a_drag_with_a_pause_is_scanned_at_the_pause_and_at_the_end():
    clock = Clock()
    scanner = Scanner(clock)
    sched = LiveScheduler(scanner, clock, LiveSettings(debounce_s=0.05))
    drag(sched, scanner, clock, "LiDAR", 10, 0.016)
    drag(sched, scanner, clock, "LiDAR", 1, 0.2)  # held still for 0.2 s
    drag(sched, scanner, clock, "LiDAR", 10, 0.016)
    run_timer(sched, clock)
    assert sched.scans == 2 and [s["LiDAR"][1] for s in scanner.shown] == [0, 9]


def test_a_newer_change_supersedes_a_scan_not_shown_yet():
    clock = Clock()
    scanner = Scanner(clock)
    sched = LiveScheduler(scanner, clock, LiveSettings(debounce_s=0.05))
    # a frame change: both LiDARs at once; A is scanned first, then A moves again
    # before B is scanned and anything is shown
    sched.changed(["A", "B"])
    clock.t += 0.05
    assert sched.tick() == 0.0 and scanner.scanned == ["A"]
    scanner.state["A"] = "moved"
    sched.changed(["A"])
    run_timer(sched, clock)
    assert scanner.scanned == ["A", "B", "A"] and sched.superseded == 1
    assert scanner.shown == [{"A": ("A", "moved"), "B": ("B", None)}]  # one update
    # a change that arrives during a scan drops that scan's result too
    scanner.during = lambda key: (sched.changed([key]), setattr(scanner, "during", None))
    sched.changed(["B"])
    run_timer(sched, clock)
    assert scanner.scanned[-2:] == ["B", "B"] and sched.superseded == 2
    assert len(scanner.shown) == 2 and sched.updates[-1].scans == 2


def test_a_scene_over_budget_falls_back_to_on_demand_and_says_so():
    clock = Clock()
    scanner = Scanner(clock, cost=0.3)  # a heavy scene: 300 ms a scan
    sched = LiveScheduler(scanner, clock, LiveSettings(debounce_s=0.05, budget_s=0.15,
                                                       strikes=2))
    for move in range(3):
        sched.changed(["LiDAR"])
        run_timer(sched, clock)
        # the first update (it prepares the scene) is not judged, then two strikes
        assert sched.mode == (LIVE if move < 2 else ON_DEMAND)
    assert "over the 150 ms budget" in sched.reason and "on demand" in sched.reason
    assert "an update takes 305 ms" in sched.reason  # the scan and the showing
    sched.changed(["LiDAR"])
    assert sched.tick() is None and sched.busy  # nothing happens by itself now
    clock.t += 1.0
    assert sched.tick() is None and sched.scans == 3
    update = sched.update_now()  # the panel's Update button
    assert update.keys == ("LiDAR",) and sched.scans == 4 and not sched.busy
    sched.resume()
    assert sched.mode == LIVE and sched.reason == ""


def test_a_light_scene_stays_live_and_an_occasional_slow_update_is_forgiven():
    clock = Clock()
    scanner = Scanner(clock, cost=0.02)
    sched = LiveScheduler(scanner, clock, LiveSettings(debounce_s=0.05, budget_s=0.15))
    for cost in (0.5, 0.02, 0.3, 0.02, 0.3, 0.02):  # never two slow ones in a row
        scanner.cost = cost
        sched.changed(["LiDAR"])
        run_timer(sched, clock)
    assert sched.mode == LIVE and len(sched.updates) == 6


def test_forgotten_lidars_are_not_scanned():
    clock = Clock()
    scanner = Scanner(clock)
    sched = LiveScheduler(scanner, clock)
    sched.changed(["A", "B"])
    sched.forget("A")
    run_timer(sched, clock)
    assert scanner.scanned == ["B"]


POLY = [(0.0, 0.0), (20.0, 0.0), (20.0, 10.0), (0.0, 10.0)]


def cloud(seed, n, label=1, shift=0.0):
    rng = np.random.default_rng(seed)
    p = empty_points(n)
    p["x"] = rng.uniform(-2, 22, n) + shift
    p["y"] = rng.uniform(-2, 12, n)
    p["label"] = label
    return p


def test_coverage_is_infra_lob_metrics_of_all_clouds_and_follows_one_rescan():
    cov = Coverage(POLY, disks=400, cell=2.0)
    a, b = cloud(1, 3000), cloud(2, 2000)
    cov.set_cloud("A", a)
    cov.set_cloud("B", b)
    ref = infra_lob_metrics([a, b], POLY, disks=400, cell=2.0)
    got = cov.state()
    assert got.sensors == ("A", "B") and got.n_points == ref.n_points
    assert got.infra_d == pytest.approx(ref.infra_d, rel=1e-12)
    assert got.infra_nuc == pytest.approx(ref.infra_nuc, rel=1e-12)
    np.testing.assert_array_equal(got.density.values, ref.density.values)
    moved = cloud(3, 2500, shift=3.0)  # B rescanned after a move
    cov.set_cloud("B", moved)
    ref = infra_lob_metrics([a, moved], POLY, disks=400, cell=2.0)
    assert cov.state().infra_nuc == pytest.approx(ref.infra_nuc, rel=1e-12)
    cov.remove("A")
    cov.remove("B")
    empty = cov.state()
    assert empty.n_points == 0 and empty.infra_d == 0 and np.isnan(empty.infra_nuc)
    assert (empty.density.values[np.isfinite(empty.density.values)] == 0).all()


def test_map_cells_are_coloured_as_the_chart_with_empty_cells_white():
    cov = Coverage([(0, 0), (4, 0), (4, 2), (2, 2), (2, 4), (0, 4)], disks=50, cell=1.0)
    p = empty_points(3)
    p["x"], p["y"], p["label"] = [0.5, 0.5, 1.5], [0.5, 0.5, 0.5], 1
    cov.set_cloud("A", p)
    corners, rgba = cells(cov.state().density)
    assert len(corners) == 12  # the L's cells; the corner outside it has none
    first = {tuple(c[0]): tuple(col) for c, col in zip(corners, rgba)}
    assert first[(0.0, 0.0)][:3] == pytest.approx(np.array([253, 231, 37]) / 255)  # densest
    assert first[(0.0, 1.0)] == pytest.approx((1.0, 1.0, 1.0, 1.0))  # no return: white
    assert corners[0][1] - corners[0][0] == pytest.approx([1.0, 1.0])


def test_map_levels_band_the_cells_as_the_chart_with_no_return_apart():
    cov = Coverage([(0, 0), (4, 0), (4, 2), (2, 2), (2, 4), (0, 4)], disks=50, cell=1.0)
    p = empty_points(10)
    # 5 points in (0,0), 4 in (1,0), 1 in (2,0): densities 5, 4, 1 per m²
    p["x"] = [0.5] * 5 + [1.5] * 4 + [2.5]
    p["y"], p["label"] = 0.5, 1
    cov.set_cloud("A", p)
    dm = cov.state().density
    corners, rgba = cells(dm)
    band = levels(dm, n=4)
    first = {tuple(c[0]): int(b) for c, b in zip(corners, band)}
    assert first[(0.0, 0.0)] == 4 and first[(1.0, 0.0)] == 4  # 4/5 = 0.8: the top band
    assert first[(2.0, 0.0)] == 1 and first[(0.0, 1.0)] == 0  # 0.2: the first; none: 0
    colours = level_colours(4)
    assert colours.shape == (5, 4) and colours[0] == pytest.approx([1, 1, 1, 1])
    # a band's colour is viridis at its middle: matplotlib's viridis(0.5) is #21918c
    assert level_colours(1)[1, :3] * 255 == pytest.approx([33, 145, 140], abs=1.0)
    assert (np.diff(colours[1:, 1]) > 0).all()  # green rises from purple to yellow
    cov.set_cloud("A", empty_points(0))  # no points: every cell is 'no return'

    assert (levels(cov.state().density, n=4) == 0).all()


# -- a still LiDAR's sampled sweep kept between live rescans (core/scan/kept_sweeps) -----

def turning(speed, yaw_rate):
    """A car driving along +y, turning and swaying: its motion needs more samples than
    the first nine."""
    def at(s):
        m = translation((4.0 + 0.2 * np.sin(60.0 * s), -8.0 + speed * s, 0.0))
        c, n = np.cos(yaw_rate * s), np.sin(yaw_rate * s)
        m[:2, :2] = [[c, -n], [n, c]]
        return m
    return at


def scan_bytes(session, scene, sensor="pole", preset=None, frame=1):
    scene.frame = frame
    result, info = session.scan(scene, sensor, preset or small_preset(), ScanSettings(), frame)
    return result.points.tobytes(), repr(info)


def moved_pole(scene, dx):
    scene.sensors["pole"] = lambda s: translation((dx, 0.0, 0.5))


def test_a_moved_still_lidar_reuses_the_frames_samples_and_equals_a_fresh_scan():
    scene = street(car_speed=12.0)
    scene.motion["car"] = turning(12.0, 2.0)
    kept = KeptSweeps()
    live = ScanSession(NumpyCaster, kept_sweeps=kept)
    first = scan_bytes(live, scene)
    assert first == scan_bytes(ScanSession(NumpyCaster), scene)
    read = scene.calls["state"]
    assert kept.misses == read // 2 and read >= 2 * 17 and kept.hits == 0  # (and the fresh)
    for dx in (0.3, 0.6, -0.2):  # the LiDAR moved: its rescans sample nothing anew
        moved_pole(scene, dx)
        got = scan_bytes(live, scene)
        assert scene.calls["state"] == read and kept.reused > 0
        want = scan_bytes(ScanSession(NumpyCaster), scene)  # a fresh scan, same state
        read = scene.calls["state"]
        assert got == want  # byte for byte: points and sidecar
    assert got != first
    # a still box added ahead of the car (its index in the read moves, its motion not):
    # the classification is given back with the car's new index
    reused = kept.reused
    scene.boxes["bench"] = ((-6.0, 3.0, -1.0), (-4.0, 4.0, 0.0), 4)
    got = scan_bytes(live, scene)
    assert kept.reused == reused + 1 and scene.calls["state"] == read
    assert got == scan_bytes(ScanSession(NumpyCaster), scene)
    # the car's bounds changed (another mesh; the fake keeps its mesh id, so a new
    # session, which has not built it): classified again, from the kept states
    scene.boxes["car"] = ((-2.0, -0.9, -1.0), (2.0, 0.9, 0.5), 11)
    read = scene.calls["state"]
    hits = kept.hits
    got = scan_bytes(ScanSession(NumpyCaster, kept_sweeps=kept), scene)
    assert kept.reused == reused + 1 and kept.hits > hits and scene.calls["state"] == read
    assert got == scan_bytes(ScanSession(NumpyCaster), scene)


def test_kept_samples_are_keyed_by_frame_and_sweep_time_and_cleared_on_an_edit():
    scene = street(car_speed=12.0)
    scene.motion["car"] = turning(12.0, 2.0)
    kept = KeptSweeps()
    live = ScanSession(NumpyCaster, kept_sweeps=kept)
    scan_bytes(live, scene)
    misses = kept.misses
    # another frame, and a preset with another sweep time: sampled anew, a fresh scan's
    fast = dataclasses.replace(small_preset(pid="fast"), frequency_hz=20.0)
    for frame, preset in ((2, None), (2, fast)):
        got = scan_bytes(live, scene, preset=preset, frame=frame)
        assert kept.misses > misses
        misses = kept.misses
        assert got == scan_bytes(ScanSession(NumpyCaster), scene, preset=preset, frame=frame)
    # another object's motion edited: the kept samples are stale until cleared (the
    # caller's contract: live coverage clears them on any edit of another object)
    scene.motion["car"] = turning(6.0, -1.0)
    fresh = scan_bytes(ScanSession(NumpyCaster), scene, frame=2)
    assert scan_bytes(live, scene, frame=2) != fresh
    kept.clear()
    assert len(kept) == 0 and scan_bytes(live, scene, frame=2) == fresh


def test_a_moving_lidar_samples_its_sweep_anew():
    scene = street(car_speed=12.0)
    scene.moving_sensors = {"pole"}
    scene.sensors["pole"] = lambda s: translation((5.0 * s, 0.0, 0.5))
    kept = KeptSweeps()
    live = ScanSession(NumpyCaster, kept_sweeps=kept)
    for _ in range(2):
        assert scan_bytes(live, scene) == scan_bytes(ScanSession(NumpyCaster), scene)
    assert kept.hits == kept.misses == kept.reused == 0 and len(kept) == 0
