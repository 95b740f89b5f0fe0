"""Every ground-truth box of a frame at once (``ground_truth.object_boxes``: one
evaluation of all tracks, the rays grouped once by direction, the counts in one pass,
compiled or numpy) against the per-object reference it replaced
(``box_reference.object_boxes_per_object``): the same boxes, number for number, for
still, driving and turning sensors, objects that drive, turn and accelerate, boxes on
the sweep's seam, objects that return nothing, and colliding instance ids."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.output import box_counts, box_reference
from rls_addon.core.output.ray_cells import RayCells
from rls_addon.core.scan import session as session_module
from rls_addon.core.scan.frame import RayRecord
from rls_addon.core.scan.run import ScanRun, SensorJob
from rls_addon.core.scan.settings import LidarSettings, OutputSettings, ScanSettings

from .fakes import FakeScene, numpy_factory, small_preset, translation


def yawed(p, yaw):
    m = translation(p)
    c, s = math.cos(yaw), math.sin(yaw)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def traffic(sensor="still"):
    """A ground, a wall, and road users around a sensor: a car driving straight, one
    turning while it brakes, a cyclist accelerating, a pedestrian behind the wall (no
    point) and one half behind it, a parked van across the sweep's seam (the sensor's
    +X), a car parked behind the wall (no point, standing still), a car far out of
    range; the sensor still, driving or turning."""
    boxes = {"ground": ((-80, -80, -1.2), (80, 80, -1.0), 1),
             "wall": ((-4.0, 6.0, -1.0), (4.0, 6.4, 3.0), 4),
             "car": ((-2.25, -0.9, 0.0), (2.25, 0.9, 1.5), 11),
             "turner": ((-2.3, -0.95, 0.0), (2.3, 0.95, 1.6), 11),
             "bike": ((-0.9, -0.3, 0.0), (0.9, 0.3, 1.7), 18),
             "walker": ((-0.3, -0.3, 0.0), (0.3, 0.3, 1.8), 12),
             "peeker": ((-0.3, -0.3, 0.0), (0.3, 0.3, 1.8), 12),
             "van": ((-2.5, -1.0, 0.0), (2.5, 1.0, 2.2), 11),
             "far": ((-2.0, -0.9, 0.0), (2.0, 0.9, 1.5), 11),
             "parked": ((-1.0, -0.9, 0.0), (1.0, 0.9, 1.5), 11)}
    motion = {
        "car": lambda s: yawed((8.0 + 14.0 * s, -6.0, -1.0), 0.0),
        # a right turn of radius 9 m at 8 m/s, slowing at 2 m/s^2
        "turner": lambda s: yawed((12 + 9 * math.sin((8 * s - s * s) / 9), 9 - 9 * math.cos(
            (8 * s - s * s) / 9), -1.0), (8 * s - s * s) / 9),
        "bike": lambda s: yawed((-3.0 + 3.0 * s * s, -12.0, -1.0), 0.2),
        "walker": lambda s: yawed((0.5 * s, 9.0, -1.0), 1.2),
        "peeker": lambda s: yawed((4.2 + 0.3 * s, 9.5, -1.0), 0.0),  # half behind the wall
        "van": lambda s: yawed((20.0, -1.0, -1.0), 0.0),
        "far": lambda s: yawed((300.0 + 10 * s, 0.0, -1.0), 0.0),
        "parked": lambda s: yawed((-1.0, 11.0, -1.0), 0.3),
    }
    sensors = {"still": lambda s: translation((0.0, 0.0, 1.0)),
               "driving": lambda s: translation((-4.0 + 12.0 * s, -2.0, 1.0)),
               "turning": lambda s: yawed((-4.0 + 10 * math.sin(0.8 * s), 8 - 10 * math.cos(
                   0.8 * s), 1.0), 0.8 * s)}
    sc = FakeScene(boxes, {sensor: sensors[sensor]}, motion)
    if sensor != "still":
        sc.moving_sensors = {sensor}
    return sc


def both_ways(monkeypatch, sc, sensor, frames=(1, 2, 3), **scan_kw):
    """Scan ``frames`` with every frame's boxes made both ways; returns how many boxes
    were compared (and asserts they are equal)."""
    compared = []
    fast = session_module.object_boxes

    def compare(*args, **kw):
        got = [json.dumps(b.to_dict()) for b in fast(*args, **kw)]
        box_counts.compiled = False
        try:
            numpy_got = [json.dumps(b.to_dict()) for b in fast(*args, **kw)]
        finally:
            box_counts.compiled = True
        ref = [json.dumps(b.to_dict())
               for b in box_reference.object_boxes_per_object(*args, **kw)]
        assert got == ref and numpy_got == ref
        compared.extend(got)
        return fast(*args, **kw)

    monkeypatch.setattr(session_module, "object_boxes", compare)
    preset = small_preset(channels=16, steps=900, noise=0.02)
    job = SensorJob(sensor, LidarSettings(scan=ScanSettings(**scan_kw),
                                          output=OutputSettings()), preset)
    ScanRun(sc, [job], list(frames), factory=numpy_factory).run()
    return compared


@pytest.mark.parametrize("sensor,seam", [("still", 0.0), ("driving", 2.4), ("turning", 0.0)])
def test_all_boxes_at_once_equal_the_per_object_reference(monkeypatch, sensor, seam):
    compared = both_ways(monkeypatch, traffic(sensor), sensor, sweep_start_deg=seam)
    boxes = [json.loads(b) for b in compared]
    assert len(boxes) == 3 * 8  # every road user, every frame
    assert any(b["split_by_sweep_seam"] for b in boxes)  # the van on the seam
    assert any(not b["seen"] for b in boxes)              # the walker behind the wall
    if sensor == "still":  # a still object that returned nothing faces a ray all the same
        assert all(not b["seen"] and b["time_s"] > 0 for b in boxes if b["object"] == "parked")
    assert any(b["seen"] and 0 < b["visible_share"] < 1 for b in boxes)  # the peeker
    assert any(b["visible_share"] is None for b in boxes)  # far out of range


def test_snapshot_motion_and_substeps_too(monkeypatch):
    assert both_ways(monkeypatch, traffic("driving"), "driving", frames=(2,),
                     motion="snapshot")
    assert both_ways(monkeypatch, traffic("turning"), "turning", frames=(2,),
                     motion="substeps", substeps=4)


def test_colliding_instance_ids_count_every_object_of_the_id(monkeypatch):
    from rls_addon.core.scene import instances as instances_module

    real = instances_module.object_table

    def colliding(insts):  # the car and the van share an id, as a name clash would
        table = real(insts)
        ids = {o.name: o.instance for o in table}
        return [type(o)(o.name, o.label, ids["car"] if o.name == "van" else o.instance)
                if o.name == "van" else o for o in table]

    monkeypatch.setattr(session_module, "object_table", colliding)
    boxes = [json.loads(b) for b in both_ways(monkeypatch, traffic("still"), "still",
                                               frames=(1,))]
    car, van = (next(b for b in boxes if b["object"] == n) for n in ("car", "van"))
    assert car["instance"] == van["instance"] and car["points"] == van["points"] > 0


def spinning_rays(rng, n_az=900, channels=16, moving=False, turning=False):
    az = np.repeat(np.linspace(-math.pi, math.pi, n_az, endpoint=False), channels)
    el = np.tile(np.radians(np.linspace(-25, 15, channels)), n_az)
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
    times = np.linspace(0, 0.1, len(dirs))
    if turning:
        yaw = 2.0 * times
        dirs = np.stack([dirs[:, 0] * np.cos(yaw) - dirs[:, 1] * np.sin(yaw),
                         dirs[:, 0] * np.sin(yaw) + dirs[:, 1] * np.cos(yaw), dirs[:, 2]], 1)
    dirs.flags.writeable = False
    origins = (np.array([[0.0, 0.0, 2.0]]) if not moving
               else np.c_[times * 15.0, times * 3.0, np.full(len(times), 2.0)])
    obj = rng.integers(-1, 4, len(dirs)).astype(np.int32)
    dist = np.where(obj >= 0, rng.uniform(1, 80, len(dirs)), np.inf)
    hit = np.repeat(np.nonzero(obj >= 0)[0], rng.integers(1, 3, np.count_nonzero(obj >= 0)))
    return RayRecord(origins, dirs, times, obj, dist, hit, [])


@pytest.mark.parametrize("moving,turning", [(False, False), (True, False), (True, True)])
def test_the_compiled_counts_equal_numpys_and_each_boxs_own(moving, turning):
    """Random boxes (near, far, over the sensor, on the seam, around the pole) and a
    spinning pattern whose rays graze box faces: the compiled counts, numpy's pairs and
    the reference's box-by-box tests agree, with points on two returns of a ray and
    ghosts among them."""
    rng = np.random.default_rng(5 + moving + turning)
    rays = spinning_rays(rng, moving=moving, turning=turning)
    ranges = rays.dist[rays.point_ray] + rng.normal(0, 0.05, len(rays.point_ray))
    real = rng.random(len(ranges)) > 0.1
    world = rays.point_world(ranges)
    n = 120
    yaw = rng.uniform(-math.pi, math.pi, n)
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = \
        np.cos(yaw), -np.sin(yaw), np.sin(yaw), np.cos(yaw)
    poses[:, :3, 3] = rng.uniform([-40, -40, -3], [40, 40, 12], (n, 3))
    poses[:10, :3, 3] = np.c_[-rng.uniform(0.5, 30, 10), rng.uniform(-0.3, 0.3, 10),
                              rng.uniform(0, 4, 10)]  # on the seam at -pi / pi
    poses[10:15, :3, 3] = [[0.1, 0.2, 2.0], [0, 0, 9.0], [0.3, -0.2, -6.0], [1.0, 0, 2.0],
                           [0, 0, 2.0]]  # holding the sensor, over and under it
    poses[15:20, :3, :3] = np.eye(3)  # axis-aligned: rays parallel to the slabs
    sizes = rng.uniform([0.5, 0.5, 1.0], [10.0, 3.0, 4.0], (n, 3))
    # the sensor's own car just under it, and boxes just over it: spheres that hold
    # the sensor, narrowed to the elevations that reach the box (RayCells._bands)
    # (long ones that the pattern's rays nearest the bounding elevation still reach)
    poses[20:24, :3, 3] = [[0.5, 0.0, 1.2], [0.5, 0.0, 0.95], [0.5, 0.0, 2.9], [0.5, 0.0, 3.05]]
    sizes[20:24] = [[4.5, 1.8, 1.4], [11.0, 2.0, 1.4], [3.0, 2.0, 1.4], [11.0, 2.0, 1.4]]
    poses[21:24, :3, :3] = np.eye(3)  # (no turn widening their world bounds)
    objects = rng.integers(-2, 4, n)
    objects[20:24] = [1, 2, 3, 0]  # objects the rays hit
    margin, rmax = 0.05, 120.0
    cells = RayCells(rays)
    radii = np.maximum(np.linalg.norm(sizes / 2 + margin, axis=1),
                       np.linalg.norm(sizes, axis=1) / 2 + 1e-6)
    extents = np.einsum("bij,bj->bi", np.abs(poses[:, :3, :3]), sizes / 2 + margin)
    segments = cells.segments(poses[:, :3, 3], radii, extents)
    narrowed = np.bincount(segments[0], segments[2] - segments[1], n)[20:24]
    assert np.all(narrowed < 0.9 * len(rays.dirs))  # fewer rays than all for each
    got = box_counts.box_counts(cells, objects, poses, sizes, margin, rmax, ranges, real,
                                segments)
    assert box_counts.BOX_COUNTS.get() is not None  # the library is built here
    ref = box_counts.box_counts_numpy(cells, objects, poses, sizes, margin, rmax, ranges,
                                      real, segments)
    for a, b in zip(got, ref):
        np.testing.assert_array_equal(a, b)
    fan = box_reference.RayFan(rays, world)
    for j in range(n):
        share, on = box_reference._visibility(rays, objects[j], poses[j], sizes[j], rmax, fan)
        inside = np.count_nonzero(real & box_reference._inside(world, poses[j], sizes[j],
                                                                margin))
        assert (on, int(got[2][j])) == (int(got[1][j]), inside)
        assert (math.isnan(share) and math.isnan(got[0][j])) or share == got[0][j]
    assert got[1].sum() > 5000 and got[2].sum() > 500  # the boxes saw a lot
    assert got[1][20:24].sum() > 1000 and got[2][20:24].sum() > 100


@pytest.mark.parametrize("moving", [False, True])
def test_the_ray_facing_a_centre_is_the_best_of_all(moving):
    from rls_addon.core.output.box_counts import facing, facing_ray

    rng = np.random.default_rng(11)
    rays = spinning_rays(rng, moving=moving)
    cells = RayCells(rays)
    settled = 0
    for _ in range(200):
        centre = rng.uniform([-40, -40, -3], [40, 40, 12])
        best = facing_ray(cells, centre)
        if best is not None:
            assert best == facing(rays, centre, slice(None))[0]
            settled += 1
    assert settled > 150


def test_every_boxs_record_made_together_is_its_own(monkeypatch):
    """The sidecar's box records made for all boxes at once (``box_dicts``: the sensor
    poses inverted and the start matrices decomposed together) are each box's own
    ``to_dict``, byte for byte, for a driving and a turning sensor."""
    from rls_addon.core.output.ground_truth import box_dicts

    seen = []
    fast = session_module.object_boxes

    def compare(*args, **kw):
        boxes = fast(*args, **kw)
        assert json.dumps(box_dicts(boxes)) == json.dumps([b.to_dict() for b in boxes])
        seen.extend(boxes)
        return boxes

    monkeypatch.setattr(session_module, "object_boxes", compare)
    for sensor in ("driving", "turning"):
        job = SensorJob(sensor, LidarSettings(scan=ScanSettings(), output=OutputSettings()),
                        small_preset(channels=16, steps=900))
        ScanRun(traffic(sensor), [job], [1, 2], factory=numpy_factory).run()
    assert len(seen) == 2 * 2 * 8 and all(b.start_matrix is not None for b in seen)


@pytest.mark.parametrize("moving,turning", [(False, False), (True, False), (True, True)])
def test_every_centres_facing_ray_at_once_is_its_own(moving, turning):
    """``facing_rays`` (every centre's cones together, widening round by round) gives
    each centre ``facing_ray``'s ray, -1 where that gives None: centres near and far,
    above and below the pattern (cones that widen), over the sensor, on the seam."""
    from rls_addon.core.output.box_counts import facing_ray, facing_rays

    rng = np.random.default_rng(13)
    rays = spinning_rays(rng, moving=moving, turning=turning)
    cells = RayCells(rays)
    centres = np.r_[rng.uniform([-40, -40, -3], [40, 40, 12], (150, 3)),
                    [[0.0, 0.0, 40.0], [5.0, 0.0, 30.0], [0.1, 0.0, 2.0], [-20.0, 0.0, -8.0],
                     [-30.0, 1e-3, 2.0], [-30.0, -1e-3, 2.0], [10.0, 10.0, 2.0]]]
    got = facing_rays(cells, centres)
    want = [facing_ray(cells, c) for c in centres]
    assert got.tolist() == [-1 if w is None else w for w in want]
    assert sum(w is None for w in want) >= 1 and sum(w is not None for w in want) > 140


@pytest.mark.parametrize("compiled", [True, False])
def test_every_boxs_time_from_its_points_at_once_is_split_at_seams(monkeypatch, compiled):
    """``_own_points`` (the points grouped by box, compiled or numpy; the groups' times
    sorted once, every median and seam test read off them) against ``split_at_seam``
    of each box's own points: odd and even counts, one point, none, ghosts, boxes on
    the seam with more early or more late points, points out of time order, two boxes
    of one id; and a time that is not finite."""
    from rls_addon.core.output.ground_truth import _own_points, split_at_seam

    monkeypatch.setattr(box_counts, "compiled", compiled)

    rng = np.random.default_rng(17)
    period = 0.1
    ids = np.array([7, 3, 9, 11, 3, 20, 21, 22], np.int64)
    n = 4000
    inst = rng.choice([3, 7, 9, 11, 20, 21, 22, 99], n).astype(np.uint32)
    times = rng.uniform(0, period, n)
    on_seam = inst == 20  # mostly early, a few late
    times[on_seam] = np.where(rng.random(on_seam.sum()) < 0.7, rng.uniform(0, 0.01, on_seam.sum()),
                              rng.uniform(0.095, 0.1, on_seam.sum()))
    late = inst == 21     # mostly late
    times[late] = np.where(rng.random(late.sum()) < 0.3, rng.uniform(0, 0.01, late.sum()),
                           rng.uniform(0.095, 0.1, late.sum()))
    inst[inst == 22] = 99
    inst[np.nonzero(inst == 99)[0][:1]] = 22  # one point
    ghost = (rng.random(n) < 0.1).astype(np.uint8)
    ghost[inst == 11] = 1  # only ghosts: no point
    for label, ordered in (("shuffled", False), ("in firing order", True)):
        t = np.sort(times) if ordered else times
        pts = np.zeros(n, [("instance", "<u4"), ("time", "<f8"), ("ghost", "u1")])
        pts["instance"], pts["time"], pts["ghost"] = inst, t, ghost
        count, got_t, got_seam = _own_points(pts, ids, period)
        for j, i in enumerate(ids):
            mine = t[(inst == i) & (ghost == 0)]
            assert count[j] == len(mine), label
            want = split_at_seam(mine, period) if len(mine) else (None, False)
            assert (got_t[j], got_seam[j]) == want, (label, i)
        assert got_seam[5] and got_seam[6] and count[7] == 1 and count[3] == 0
        assert count[1] == count[4] > 0 and {int(c) % 2 for c in count[count > 1]} == {0, 1}
    first7 = np.nonzero(inst == 7)[0][0]
    pts["time"][first7], pts["ghost"][first7] = np.nan, 0
    count, got_t, _ = _own_points(pts, ids, period)
    want = split_at_seam(pts["time"][(inst == 7) & (ghost == 0)], period)
    assert math.isnan(got_t[0]) == math.isnan(want[0])


def test_the_compiled_grouping_of_points_is_numpys():
    """``box_counts.own_groups`` (one compiled pass over the scan's point records, their
    fields unaligned) gives ``_own_groups_numpy``'s groups and times, for points of a
    moving scan's layout with ghosts and ids not among the boxes' (some sharing a key's
    low 16 bits); None for records
    it cannot read (ids of another type), where numpy's are used."""
    from rls_addon.core.output.ground_truth import _own_groups_numpy
    from rls_addon.core.points import POINT_DTYPE

    rng = np.random.default_rng(23)
    n = 20000
    pts = np.zeros(n, POINT_DTYPE)
    # 5 + 2 ** 16 and 1000 + 2 ** 17: the low 16 bits of a key (the compiled pass's
    # filter lets them by), not a key
    pts["instance"] = rng.choice([0, 5, 6, 40, 2 ** 32 - 1, 77, 1000, 5 + 2 ** 16,
                                  1000 + 2 ** 17, 2 ** 32 - 2 ** 16 + 40], n)
    pts["time"] = np.sort(rng.uniform(0, 0.1, n)) + rng.normal(0, 1e-4, n)  # not all in order
    pts["ghost"] = rng.random(n) < 0.15
    keys = np.array([5, 40, 41, 1000, 2 ** 32 - 1], np.uint32)  # 41: no point
    for view in (pts, pts[::3]):
        got = box_counts.own_groups(view, keys)
        assert got is not None  # the library is built here
        want = _own_groups_numpy(view, keys.astype(np.int64))
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        assert got[0][2] == got[0][3] and len(got[1]) > n / 10 * (1 if view is pts else 0.3)
    other = np.zeros(5, [("instance", "<i8"), ("time", "<f8"), ("ghost", "u1")])
    assert box_counts.own_groups(other, keys) is None


def test_every_moving_objects_velocity_at_once_is_its_own():
    """``_velocities_from`` (all moving objects' centre velocities in one product)
    equals ``_velocity_from`` object by object, bit for bit: turned, scaled and sheared
    matrices, spans of different lengths."""
    from rls_addon.core.output.ground_truth import _velocities_from, _velocity_from

    rng = np.random.default_rng(29)
    n = 40
    m = np.repeat(np.eye(4)[None], 2 * n, axis=0)
    m[:, :3, :] = rng.normal(0, 3, (2 * n, 3, 4))
    centres = rng.uniform(-3, 3, (n, 3))
    spans = np.c_[rng.uniform(0, 0.1, n), np.zeros(n)]
    spans[:, 1] = spans[:, 0] + rng.uniform(1e-4, 2e-3, n)
    got = _velocities_from(m.reshape(n, 2, 4, 4), centres, spans)
    want = [_velocity_from(np.ascontiguousarray(m[2 * j:2 * j + 2]), centres[j], *spans[j])
            for j in range(n)]
    assert got.tobytes() == np.array(want).tobytes()


def test_a_still_box_that_returned_nothing_faces_its_ray_once(monkeypatch):
    """The reference time of a box with no point is found again at the time found, as
    ``box_reference`` does; a box that stood still is where it was, so it keeps the ray
    it faced and is not looked for again (every parked car out of sight, every frame).
    Its times are the reference's either way."""
    from rls_addon.core.output import ground_truth
    from rls_addon.core.scene.motion import Track
    from rls_addon.core.scene.track_set import TrackSet

    rays = spinning_rays(np.random.default_rng(17), moving=True)
    cells = RayCells(rays)
    times = np.linspace(0.0, 0.1, 5)
    driving = Track(times, np.stack([translation((5.0 + 10 * s, 3.0, 0.0)) for s in times]))
    tset = TrackSet.of([None, driving, None],
                       [translation((-6.0, 2.0, 0.5)), None, translation((0.0, -9.0, 1.0))])
    centres = np.zeros((3, 3))
    asked = []
    real = box_counts.facing_rays

    def counted(cells_, c):
        asked.append(len(c))
        return real(cells_, c)

    monkeypatch.setattr(box_counts, "facing_rays", counted)
    got = ground_truth._times_facing(cells, tset, [0, 1, 2], centres)
    assert asked == [3, 1]  # the driving car alone in the second round
    for j in range(3):
        t = float(rays.times[0])
        for _ in range(2):
            centre = (tset.tracks[j].at([t])[0] @ np.r_[centres[j], 1.0])[:3]
            t = float(rays.times[box_counts.facing(rays, centre, slice(None))[0]])
        assert got[j] == t
