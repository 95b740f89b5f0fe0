"""A study keeps counts, not clouds (issue 18): each candidate's scan gives its counts
(points in the region, per disk, per vehicle-frame) and no per-point array; the density
maps of the sets drawn come from scanning their members again with the same seeds, and
equal the maps of the points the candidates' counts came from."""

import dataclasses
import pickle

import numpy as np
import pytest

from rls_addon.core.casting import NumpyCaster
from rls_addon.core.scan.frame import scan_frame
from rls_addon.core.metrics.infra import density_map
from rls_addon.core.study.scanner import CandidateScan, StudyScanner, study_inputs
from rls_addon.core.study.config import StudyConfig
from rls_addon.core.study.loop import run_study

from .test_study import FakeStudyScene, TrafficStudyScene

KEPT_LIMIT = 50_000  # bytes kept per candidate (issue 18)


def numpy_factory(name):
    return NumpyCaster, None


def full_scan(scanner, cand, frame, moving=()):
    """The candidate's frame as the study scanned it before it kept only counts: the
    study's prepared scene, every point field assembled."""
    return scan_frame(scanner.prepared, scanner.preset.pattern(frame), cand.pose,
                      scanner.preset, scanner.settings, frame=frame, sensor=cand.name,
                      moving=list(moving)).points


def expected_map(result, members):
    """The density map of ``members`` from their full scans (the kept-xy way)."""
    xy = [result.layout.select([full_scan(result.scanner, result.candidates[i], result.frame)],
                               [1, 2]) for i in members]
    return density_map(np.concatenate(xy), result.polygon, result.config.cell)


def scanner_of(scene, cfg):
    inputs = study_inputs(scene, cfg)
    return StudyScanner(scene, cfg, inputs.preset, inputs.polygon, inputs.layout,
                        inputs.candidates, numpy_factory), inputs.candidates


@pytest.mark.parametrize("traffic", [(), (1, 3)])
def test_candidate_scans_hold_counts_and_no_points(traffic):
    assert "xy" not in {f.name for f in dataclasses.fields(CandidateScan)}
    scene = TrafficStudyScene() if traffic else FakeStudyScene()
    cfg = StudyConfig(k=(1,), disks=300, noise=False, dropout=False, traffic_frames=traffic)
    scanner, cands = scanner_of(scene, cfg)
    got = scanner.scan(cands[-1])
    assert got.n_points > 2000 and got.scan_points > got.n_points
    assert got.disk_counts.shape == (300,) and got.disk_counts.sum() > 0
    arrays = {f.name: getattr(got, f.name) for f in dataclasses.fields(got)
              if isinstance(getattr(got, f.name), np.ndarray)}
    want = {"disk_counts": (300,)}
    if traffic:
        want["vehicle_points"] = (len(scanner.vehicle_frames),)
        assert 0 < len(scanner.vehicle_frames) < 100
    assert {k: v.shape for k, v in arrays.items()} == want  # one value per disk, per vehicle


def test_a_candidate_scan_ships_under_50_kb():
    """With the default 6000 disks, what a worker sends back for a candidate."""
    cfg = StudyConfig(k=(1,), noise=False, dropout=False)
    scanner, cands = scanner_of(FakeStudyScene(), cfg)
    got = scanner.scan(cands[-1])
    assert got.n_points > 2000 and len(got.disk_counts) == 6000
    assert len(pickle.dumps(got)) < KEPT_LIMIT


@pytest.fixture(scope="module")
def study():
    """Six candidates of thousands of points each, 6000 disks, noise and dropout on."""
    cfg = StudyConfig(k=(1, 2), pitches=(0.0, 20.0))
    return run_study(FakeStudyScene(), cfg, factory=numpy_factory)


def test_memory_kept_per_candidate_is_bounded(study):
    """What a study keeps per candidate (its counts, its pose) is under 50 KB; points
    are held only for the members of the sets whose maps are drawn."""
    res = study
    assert min(c.n_points for c in res.candidates) > 2000
    assert res.counts.counts.shape == (6, 6000)
    for i, c in enumerate(res.candidates):
        kept = (res.counts.counts[i].nbytes + res.counts.n[i:i + 1].nbytes
                + res.counts.groups[i:i + 1].nbytes + c.pose.nbytes)
        assert kept < KEPT_LIMIT, (c.name, kept)
        assert all(v.size <= 16 for v in vars(c).values() if isinstance(v, np.ndarray))
    drawn = {i for s in res.searches.values() for i in s.best.members}
    assert set(res.kept) == drawn and len(drawn) < len(res.candidates)
    assert not hasattr(res, "xy")


def test_density_maps_from_rescans_equal_the_kept_points_maps(study):
    res = study
    sets = {s.best.members for s in res.searches.values()}
    sets.add(res.searches[2].evaluated[-1].members)  # a set whose map is not drawn
    for members in sets:
        want = expected_map(res, members)
        got = res.density(members)
        np.testing.assert_array_equal(got.values, want.values)
        assert got.to_dict() == want.to_dict()
    # the counts came from the same points
    for i in {i for m in sets for i in m}:
        xy = res.kept_xy(i)
        assert len(xy) == res.candidates[i].n_points
        np.testing.assert_array_equal(res.layout.counts(xy), res.counts.counts[i])


def test_density_maps_of_a_run_on_workers_come_from_the_client_scanner():
    """A sharded run: workers (their own scanners, built from the same scene and
    settings) send back pickled counts; the maps are scanned again by the run's own
    scanner and equal the serial run's."""
    cfg = StudyConfig(k=(1, 2), disks=300)
    shipped = []

    def scan_all(scanner, cands, on_scan):
        worker, worker_cands = scanner_of(FakeStudyScene(), cfg)
        assert worker is not scanner
        for c in reversed(worker_cands):  # any order
            got = pickle.loads(pickle.dumps(worker.scan(c)))
            shipped.append(len(pickle.dumps(got)))
            on_scan(got)

    sharded = run_study(FakeStudyScene(), cfg, factory=numpy_factory, scan_all=scan_all)
    serial = run_study(FakeStudyScene(), cfg, factory=numpy_factory)
    assert len(shipped) == 3 and max(shipped) < 5_000
    np.testing.assert_array_equal(sharded.counts.counts, serial.counts.counts)
    for k, s in serial.searches.items():
        assert sharded.searches[k].best.members == s.best.members
        np.testing.assert_array_equal(sharded.density(s.best.members).values,
                                      serial.density(s.best.members).values)


def test_traffic_counts_and_maps_equal_full_scans():
    """With the traffic in view only instance and ghost are gathered for the traffic
    frames: the points on each vehicle-frame are those of a full scan, and the maps
    (scanned again after the traffic frames) those of the static scan."""
    scene = TrafficStudyScene()
    cfg = StudyConfig(k=(1, 2), disks=200, noise=False, dropout=False, traffic_frames=(1, 3))
    res = run_study(scene, cfg, factory=numpy_factory)
    scanner = res.scanner
    for c in res.candidates:
        want = []
        for f, group, scored in scanner.traffic:
            pts = full_scan(scanner, c, f, moving=[group] if group is not None else [])
            pts = pts[pts["ghost"] == 0]
            want += [int(np.count_nonzero(pts["instance"] == iid)) for _, iid in scored]
        assert res.visibility.counts.counts[c.index].tolist() == want
    for s in res.searches.values():
        np.testing.assert_array_equal(res.density(s.best.members).values,
                                      expected_map(res, s.best.members).values)


@pytest.mark.parametrize("noise", [False, True])
def test_candidates_cast_only_rays_toward_the_region_and_count_the_same(noise):
    """A candidate casts the rays whose half-lines cross the region; its counts are
    those of its whole frame (every point lies on its ray's half-line)."""
    cfg = StudyConfig(k=(1,), disks=500, noise=noise, dropout=noise)
    scanner, cands = scanner_of(FakeStudyScene(), cfg)
    n = len(scanner.preset.pattern(scanner.frame))
    culled = 0
    for cand in cands:
        got = scanner.scan(cand)
        xy = scanner.layout.select([full_scan(scanner, cand, scanner.frame)],
                                   scanner.label_ids)
        assert got.n_points == len(xy) > 500
        np.testing.assert_array_equal(got.disk_counts, scanner.layout.counts(xy))
        np.testing.assert_array_equal(scanner.kept_xy(cand), xy)
        culled += got.rays < n
    assert culled == len(cands)  # the mounts stand outside the region
