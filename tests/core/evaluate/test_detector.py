"""RoadsideDetector on synthetic range images (tests/core/evaluate/synthetic.py), driven
through the detector protocol (learn, view, detect): the background, the foreground,
clustering, fusion, box fitting, determinism."""

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.detections import Boxes
from rls_addon.core.evaluate.detector import RoadsideDetector, detect_frame, learn_sensors
from rls_addon.core.evaluate.detector.background import BackgroundModel
from rls_addon.core.evaluate.detector.clustering import cluster, columns
from rls_addon.core.evaluate.detector.priors import CYCLIST, PEDESTRIAN, VEHICLE
from rls_addon.core.points import empty_points

from .synthetic import Solid, car, frames, pose, scan

# Tolerances for a box fitted to a fully or L-shape visible car (the car is larger than
# the vehicle prior, so its size comes from the points, not from the prior).
CENTRE_TOL = 0.25
SIZE_TOL = 0.2
YAW_TOL = np.radians(3.0)

POLE = pose(0.0, 0.0, 6.0)
WALL = Solid(45.0, 0.0, 1.0, 40.0, 0.0, 0.0, 10.0)            # a facade behind the street
MAST = Solid(14.0, -9.0, 0.3, 0.3, 0.0, 0.0, 5.0)             # a pole beside the street
STATIC = (WALL, MAST)


class Learned:
    """A detector and what it learned of its sensors: ``detect`` and ``foreground`` of
    one frame through the protocol."""

    def __init__(self, detector, sweeps, poses):
        self.detector = detector
        self.learned = learn_sensors(detector, sweeps, poses)

    def detect(self, points, poses, frame=0):
        return detect_frame(self.detector, self.learned, points, poses, frame)

    def foreground(self, points, poses):
        """(world xyz, sensor index, pixel) of every sensor's view of a frame."""
        if not isinstance(points, dict):
            points, poses = dict(enumerate(points)), dict(enumerate(poses))
        views = [self.detector.view(self.learned[k], points[k], poses[k]) for k in points]
        return (np.concatenate([v.xyz for v in views]),
                np.concatenate([np.full(len(v.xyz), k) for k, v in enumerate(views)]),
                np.concatenate([v.pixel for v in views]))


def learn(sweeps, poses, **kw):
    return Learned(RoadsideDetector(**kw), sweeps, poses)


_LEARNED = {}


def learned(sensor_pose=POLE, static=STATIC, n=5, **kw):
    """A detector that learned ``n`` frames of the static scene (kept for the module:
    detecting does not change a detector)."""
    key = (sensor_pose.tobytes(), repr(static), n, repr(sorted(kw.items())))
    if key not in _LEARNED:
        _LEARNED[key] = learn([frames(sensor_pose, static, n=n)], [sensor_pose], **kw)
    return _LEARNED[key]


def yaw_diff(a, b):
    """Heading difference up to a half turn (a box is the same turned by pi)."""
    d = np.mod(a - b + np.pi / 2, np.pi) - np.pi / 2
    return abs(d)


def assert_matches(det_box, placed, centre_tol=CENTRE_TOL, size_tol=SIZE_TOL, yaw_tol=YAW_TOL):
    assert np.hypot(*(det_box[:2] - placed[:2])) <= centre_tol, (det_box, placed)
    assert abs(det_box[3] - placed[3]) <= size_tol, (det_box, placed)
    assert abs(det_box[4] - placed[4]) <= size_tol, (det_box, placed)
    assert yaw_diff(det_box[6], placed[6]) <= yaw_tol, (det_box, placed)


def test_unchanged_frame_has_no_foreground():
    det = learned()
    frame = scan(POLE, STATIC, seed=7)
    xyz, _, _ = det.foreground([frame], [POLE])
    assert len(xyz) == 0
    assert len(det.detect([frame], [POLE])) == 0


def test_car_seen_from_a_pole_gives_one_matching_box():
    det = learned()
    placed = car(18.0, 7.0, yaw=np.radians(25.0), length=4.8, width=1.9)
    boxes = det.detect([scan(POLE, STATIC + (placed,), seed=3)], [POLE], frame=4)
    assert len(boxes) == 1
    assert boxes.label[0] == VEHICLE and boxes.frame[0] == 4
    assert_matches(boxes.box[0], placed.box)
    assert 0.0 < boxes.score[0] <= 1.0
    # height: from the lowest visible point (the body's lower edge) to the roof
    assert abs(boxes.box[0, 2] - placed.box[2]) < 0.3
    assert abs(boxes.box[0, 5] - placed.box[5]) < 0.3


def test_l_shape_of_a_car_seen_from_one_corner():
    """A sensor below the roof sees two sides only: the L-shape fit must still find the
    heading and both extents."""
    low = pose(0.0, 0.0, 1.6)
    det = learned(low, ())
    placed = car(14.0, 6.0, yaw=np.radians(-20.0), length=4.8, width=1.9)
    frame = scan(low, (placed,), seed=3)
    boxes = det.detect([frame], [low])
    assert len(boxes) == 1
    assert_matches(boxes.box[0], placed.box)


def test_one_side_seen_is_grown_to_the_prior_away_from_the_sensor():
    """A car seen side-on from the height of its roof shows one face: its width comes
    from the vehicle prior, and the box grows away from the sensor."""
    low = pose(0.0, 0.0, 1.0)
    det = learned(low, ())
    placed = car(15.0, 0.0, yaw=np.radians(90.0), length=4.5, width=1.8)
    boxes = det.detect([scan(low, (placed,), seed=3)], [low])
    assert len(boxes) == 1
    b = boxes.box[0]
    assert abs(b[4] - 1.8) < 0.05             # the prior's width
    assert b[0] > 15.0 - 0.2                  # grown away from the sensor, not towards it
    assert_matches(b, placed.box, centre_tol=0.3)


@pytest.mark.parametrize("second", [car(22.0, 2.6), car(28.0, 0.0)],
                         ids=["side by side, 0.8 m apart", "queued, 1.5 m apart"])
def test_two_cars_close_together_are_two_boxes(second):
    det = learned()
    first = car(22.0, 0.0)
    boxes = det.detect([scan(POLE, STATIC + (first, second), seed=5)], [POLE])
    assert len(boxes) == 2
    assert (boxes.label == VEHICLE).all()
    for placed in (first, second):
        k = int(np.argmin(np.hypot(*(boxes.box[:, :2] - placed.box[:2]).T)))
        # the queued car's near end is hidden behind the first: 0.3 m on its centre
        assert_matches(boxes.box[k], placed.box, centre_tol=0.3)


def test_crossing_cars_whose_points_touch_are_split():
    det = learned()
    a, b = car(20.0, 0.0, yaw=0.0), car(22.5, 1.5, yaw=np.pi / 2)
    boxes = det.detect([scan(POLE, STATIC + (a, b), seed=5)], [POLE])
    assert len(boxes) == 2
    for placed in (a, b):
        k = int(np.argmin(np.hypot(*(boxes.box[:, :2] - placed.box[:2]).T)))
        assert_matches(boxes.box[k], placed.box, centre_tol=0.5, size_tol=0.4,
                       yaw_tol=np.radians(6))


def test_a_car_cut_in_two_by_a_pole_in_front_is_one_box():
    pole = Solid(10.0, 0.0, 0.5, 0.5, 0.0, 0.0, 8.0)
    det = learned(static=STATIC + (pole,))
    placed = car(20.0, 0.0, yaw=np.pi / 2)
    frame = scan(POLE, STATIC + (pole, placed), seed=5)
    boxes = det.detect([frame], [POLE])
    assert len(boxes) == 1
    assert_matches(boxes.box[0], placed.box, centre_tol=0.3)
    # the two halves really are apart: without merging they stay two
    unmerged = learn([frames(POLE, STATIC + (pole,), n=5)], [POLE], merge_gap=0.0)
    assert len(unmerged.detect([frame], [POLE])) == 2


GLASS = Solid(30.0, 0.0, 1.0, 30.0, 0.0, 0.0, 12.0, glossy=True)


def test_a_cell_flipping_between_two_ranges_is_not_foreground():
    """Glass whose every return is either the glass or a ghost 5 m behind it, flipping
    frame by frame (ghost, ghost, glass, ...): both ranges are background, so neither state
    is foreground. A one-mode background keeps the commoner ghost and makes the glass
    foreground."""
    sweeps = [scan(POLE, (GLASS,), seed=200 + k, flip=k % 3 != 2) for k in range(6)]
    model = BackgroundModel.learn(sweeps, margin=0.3)
    glass_cells = (~np.isnan(model.modes[:, 1])).sum()
    assert glass_cells > 1000
    assert model.support[~np.isnan(model.modes[:, 1]), :2].min() > 0.3  # 1/3 and 2/3
    for state in (False, True):
        fg, _, _, _ = model.foreground(scan(POLE, (GLASS,), seed=999, flip=state))
        assert not fg.any()
    one_mode = BackgroundModel.learn(sweeps, margin=0.3, max_modes=1)
    near = scan(POLE, (GLASS,), seed=999, flip=False)
    assert one_mode.foreground(near)[0].sum() > 1000


@pytest.mark.slow  # many synthetic frames learned
def test_a_glossy_facade_flipping_at_random_gives_no_boxes():
    """Flips drawn per ray and frame (as RLS draws ghosts): after 20 learning frames,
    less than 1% of the facade's returns are foreground (a cell whose glass was seen in
    fewer than 30% of them by chance) and nothing is detected."""
    sweeps = frames(POLE, (GLASS,), n=20, seed=200)
    frame = scan(POLE, (GLASS,), seed=999)
    fg, _, _, _ = BackgroundModel.learn(sweeps, margin=0.3).foreground(frame)
    assert fg.sum() < 0.01 * len(frame)
    det = learn([sweeps], [POLE])
    assert len(det.foreground([frame], [POLE])[0]) < 0.01 * len(frame)
    assert len(det.detect([frame], [POLE])) == 0


def test_a_sparse_device_s_rings_across_a_roof_are_one_car():
    """32 rings over 35 degrees cross a car's roof as lines 1-1.7 m apart (more than
    DBSCAN's eps) with nothing between them in the range image: they merge."""
    sparse = np.linspace(-30.0, 5.0, 32)
    det = learn([[scan(POLE, STATIC, seed=100 + k, elevations_deg=sparse) for k in range(4)]],
                [POLE])
    placed = car(18.0, 7.0, yaw=np.radians(25.0))
    frame = scan(POLE, STATIC + (placed,), seed=3, elevations_deg=sparse)
    xyz, which, pixel = det.foreground([frame], [POLE])
    assert (cluster(det.detector, columns(det.detector, xyz)[0]).max() + 1) >= 3  # 3 lines
    boxes = det.detect([frame], [POLE])
    assert len(boxes) == 1 and boxes.label[0] == VEHICLE
    assert np.hypot(*(boxes.box[0, :2] - placed.box[:2])) < 0.5


@pytest.mark.slow  # many synthetic frames learned
def test_a_car_that_stood_through_most_learning_frames_is_not_background():
    """Learning from frames with traffic: a car that stood for 60% of them and left is
    one long run of frames, not background, so it is found when it stands there again."""
    parked = car(20.0, -4.0, yaw=0.2)
    sweeps = [scan(POLE, STATIC + ((parked,) if k < 18 else ()), seed=300 + k)
              for k in range(30)]
    det = learn([sweeps], [POLE])
    boxes = det.detect([scan(POLE, STATIC + (parked,), seed=5)], [POLE])
    assert len(boxes) == 1
    assert_matches(boxes.box[0], parked.box, centre_tol=0.3)


def test_returns_where_the_background_had_none_are_kept_only_when_plausible():
    """Beyond the end of the ground (cells that never returned) a car is found, a bird
    high above the road is not."""
    far_car = car(62.0, 3.0, yaw=0.7)
    bird = Solid(30.0, -3.0, 0.6, 0.6, 0.0, 7.8, 8.3)
    det = learn([frames(POLE, (), n=3, ground_radius=50.0)], [POLE])
    frame = scan(POLE, (far_car, bird), seed=9, ground_radius=50.0)
    xyz, _, _ = det.foreground([frame], [POLE])
    assert len(xyz) > 0 and (xyz[:, 2] < 4.5).all()
    boxes = det.detect([frame], [POLE])
    assert len(boxes) == 1
    assert boxes.label[0] == VEHICLE
    assert np.hypot(*(boxes.box[0, :2] - far_car.box[:2])) < 1.0


def test_two_sensors_fused_give_one_box():
    a = pose(0.0, 0.0, 6.0)
    b = pose(40.0, 22.0, 6.0, yaw=np.pi)
    static = (MAST,)
    det = learn([frames(a, static, n=4), frames(b, static, n=4, seed=50)], [a, b])
    placed = car(20.0, 10.0, yaw=np.radians(35.0), length=4.8, width=1.9)
    pa, pb = scan(a, static + (placed,), seed=1), scan(b, static + (placed,), seed=2)
    boxes = det.detect([pa, pb], [a, b])
    assert len(boxes) == 1
    assert_matches(boxes.box[0], placed.box)
    # by name as well as by order
    named = learn({"a": frames(a, static, n=4), "b": frames(b, static, n=4, seed=50)},
                  {"a": a, "b": b})
    assert np.array_equal(named.detect({"a": pa, "b": pb}, {"a": a, "b": b}).box, boxes.box)


def test_sensors_learned_apart_fuse_as_one_set():
    """A study learns each candidate once and fuses any set of them: what each sensor's
    view gives, detected together, is what detect_frame gives with both, bit for bit; a
    set's ground is its members' alone."""
    a = pose(0.0, 0.0, 6.0)
    b = pose(40.0, 22.0, 6.0, yaw=np.pi)
    static = (MAST,)
    det = RoadsideDetector()
    la = det.learn("a", frames(a, static, n=4), a)
    lb = det.learn("b", frames(b, static, n=4, seed=50), b)
    placed = (car(20.0, 10.0, yaw=np.radians(35.0)), car(8.0, -4.0, yaw=0.2))
    points = {"a": scan(a, static + placed, seed=1), "b": scan(b, static + placed, seed=2)}
    want = detect_frame(det, {"a": la, "b": lb}, points, {"a": a, "b": b})
    got = det.detect([(la, det.view(la, points["a"], a)), (lb, det.view(lb, points["b"], b))])
    assert len(want) == 2 and got.box.tobytes() == want.box.tobytes()
    assert got.score.tobytes() == want.score.tobytes()
    alone = det.detect([(la, det.view(la, points["a"], a))])
    assert det.ground_of([la]) is la.ground and det.ground_of([la, lb]) is not la.ground
    assert len(alone) >= 1


def test_same_input_same_boxes_bit_for_bit():
    placed = (car(18.0, 7.0, yaw=0.4), car(25.0, -3.0, yaw=-0.1), car(30.0, 6.0, yaw=1.2))
    frame = scan(POLE, STATIC + placed, seed=11)
    fresh = learn([frames(POLE, STATIC, n=5)], [POLE])
    one = learned().detect([frame], [POLE])
    two = fresh.detect([frame.copy()], [POLE])
    again = learned().detect([frame], [POLE])
    assert len(one) == 3
    for other in (two, again):
        assert one.box.tobytes() == other.box.tobytes()
        assert one.score.tobytes() == other.score.tobytes()
        assert np.array_equal(one.label, other.label)


def test_empty_input_gives_no_boxes():
    det = learned()
    for empty in (empty_points(0), np.zeros((0, 4)), None):
        boxes = det.detect([empty], [POLE], frame=3)
        assert isinstance(boxes, Boxes) and len(boxes) == 0
    # a background learned from empty frames: nothing to compare with, nothing plausible
    det = learn([[empty_points(0), empty_points(0)]], [POLE])
    assert len(det.detect([empty_points(0)], [POLE])) == 0


def test_learning_from_no_frames_is_refused():
    with pytest.raises(InputError, match="at least one frame"):
        learn([[]], [POLE])


def test_points_without_ring_use_elevation_bins():
    """The KITTI layout's (N, 4) x y z intensity points: rows by elevation."""
    def plain(p):
        return np.stack([p["x"], p["y"], p["z"], p["intensity"]], 1).astype(np.float32)

    det = learn([[plain(f) for f in frames(POLE, STATIC, n=4)]], [POLE])
    assert not det.learned[0].model.grid.use_ring
    placed = car(18.0, 7.0, yaw=np.radians(25.0), length=4.8, width=1.9)
    boxes = det.detect([plain(scan(POLE, STATIC + (placed,), seed=3))], [POLE])
    assert len(boxes) == 1
    assert_matches(boxes.box[0], placed.box)


def test_a_pedestrian_is_small_and_not_a_vehicle():
    det = learned()
    person = Solid(14.0, 3.0, 0.5, 0.6, 0.0, 0.0, 1.75)
    boxes = det.detect([scan(POLE, STATIC + (person,), seed=3)], [POLE])
    assert len(boxes) == 1 and boxes.label[0] == PEDESTRIAN
    assert np.hypot(*(boxes.box[0, :2] - person.box[:2])) < 0.4


def test_detect_needs_a_background():
    with pytest.raises(InputError):
        detect_frame(RoadsideDetector(), {}, [scan(POLE, ())], [POLE])


def test_a_sensor_that_moved_since_learning_is_refused():
    det = learned()
    with pytest.raises(InputError, match="still sensors"):
        det.detect([scan(POLE, STATIC)], [pose(0.5, 0.0, 6.0)])


SUMO_PEOPLE = {PEDESTRIAN: ((0.21, 0.48, 1.72, 5),), CYCLIST: ((1.6, 0.65, 1.7, 2),)}


def test_people_walking_abreast_are_two_pedestrians_and_a_cyclist_one():
    """SUMO's pedestrians walk in stripes 0.64 m apart: two abreast leave 0.16 m between
    their shoulders, which clustering bridges; the gap along the cluster splits them. A
    cyclist's points leave no such gap: it stays one. Both at the scene's own sizes."""
    det = learned(types=SUMO_PEOPLE)
    a = Solid(12.0, 3.0, 0.21, 0.48, 0.0, 0.0, 1.72)
    b = Solid(12.0, 3.64, 0.21, 0.48, 0.0, 0.0, 1.72)
    bike = Solid(14.0, -4.0, 1.6, 0.65, 0.3, 0.0, 1.7)
    boxes = det.detect([scan(POLE, STATIC + (a, b, bike), seed=3)], [POLE])
    peds = boxes.box[boxes.label == PEDESTRIAN]
    assert len(peds) == 2 and (boxes.label == CYCLIST).sum() == 1
    for placed in (a, b):
        k = int(np.argmin(np.hypot(*(peds[:, :2] - placed.box[:2]).T)))
        assert np.hypot(*(peds[k, :2] - placed.box[:2])) < 0.12
        assert sorted(peds[k, 3:5]) == pytest.approx([0.21, 0.48], abs=0.08)
    cyc = boxes.box[boxes.label == CYCLIST][0]
    assert np.hypot(*(cyc[:2] - bike.box[:2])) < 0.3
    # the same pair with the built-in priors: a pedestrian's bound (1.3 m) holds both
    assert (learned().detect([scan(POLE, STATIC + (a, b), seed=3)], [POLE]).label
            == PEDESTRIAN).sum() == 1


def test_boxes_of_little_evidence_are_not_reported():
    """A far car's low side seen as a sliver by a few dozen returns: grown to a car, its
    points cover a twentieth of the footprint, below the confidence a box needs
    (min_score 0.4): no box; with min_score 0 there is one."""
    sliver = Solid(38.0, 10.0, 2.8, 0.1, 0.0, 0.3, 0.85)
    frame = scan(POLE, STATIC + (sliver,), seed=4)
    assert len(learned().detect([frame], [POLE])) == 0
    kept = learned(min_score=0.0).detect([frame], [POLE])
    assert len(kept) == 1 and kept.label[0] == VEHICLE and kept.score[0] < 0.4


SUMO_VEHICLES = {VEHICLE: ((4.6, 1.8, 1.5, 14), (2.2, 0.9, 1.5, 2), (6.5, 2.16, 2.86, 2),
                           (12.0, 2.5, 3.4, 1))}


def test_a_queue_standing_bumper_to_bumper_is_cars():
    """Cars 0.4 m apart at a red light cluster as one long vehicle; with the scene's
    types no type shows that whole, and the gap along it cuts it into cars. Without the
    scene's types (a truck's cab and trailer could pass for a queue) it stays one."""
    first, second = car(16.0, 4.0, length=4.6), car(21.0, 4.0, length=4.6)
    frame = scan(POLE, STATIC + (first, second), seed=6)
    boxes = learned(types=SUMO_VEHICLES).detect([frame], [POLE])
    assert len(boxes) == 2 and (boxes.label == VEHICLE).all()
    for placed in (first, second):
        k = int(np.argmin(np.hypot(*(boxes.box[:, :2] - placed.box[:2]).T)))
        assert_matches(boxes.box[k], placed.box, centre_tol=0.3)
    assert len(learned().detect([frame], [POLE])) == 1


def test_a_vehicle_its_type_shows_whole_is_never_cut_at_a_gap():
    """A van's roof with a 0.4 m strip missing (a pole's shadow) leaves the same gap as
    a queue, but its type shows it whole: it stays one; two cars' roofs 0.4 m apart are
    cut."""
    from rls_addon.core.evaluate.detector.clustering import split_at_gaps

    det = RoadsideDetector(types=SUMO_VEHICLES)

    def roof(x0, x1, width=2.16, height=2.86):
        xs, ys = np.meshgrid(np.arange(x0, x1, 0.05), np.arange(-width / 2, width / 2, 0.05))
        pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, height)], 1)
        return np.vstack([pts, [[x0, 0.0, 0.0]]])  # its foot on the ground: its height

    van = np.vstack([roof(0.0, 3.0), roof(3.4, 6.5)])
    groups, _ = split_at_gaps(det, van, [np.arange(len(van))], [0.0])
    assert len(groups) == 1
    cars = np.vstack([roof(0.0, 4.6, 1.8, 1.5), roof(5.0, 9.6, 1.8, 1.5)])
    groups, _ = split_at_gaps(det, cars, [np.arange(len(cars))], [0.0])
    assert sorted(len(g) for g in groups) == [len(cars) // 2, len(cars) - len(cars) // 2]
