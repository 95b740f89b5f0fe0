"""RLS's built-in detector for still roadside LiDARs: background subtraction, DBSCAN, an
oriented box per object. CPU only, deterministic, nothing trained, so a scene can be
simulated and scored anywhere. It meets the detector protocol (``protocol.py``):

    det = RoadsideDetector(noise_sigma=0.02)
    learned = {s: det.learn(s, sweeps[s], poses[s]) for s in sensors}   # background
    boxes = det.detect([(learned[s], det.view(learned[s], points[s], poses[s]))
                        for s in sensors], frame=7)                    # fused frame
    # or: protocol.learn_sensors(det, sweeps, poses); protocol.detect_frame(...)

Inputs, per sensor: points in the SENSOR frame (x forward, y left, z up; metres), as RLS
writes them with ``frame_space = sensor`` or as a device reports them: a structured array
with x, y, z and, best, ring; or an (N, >=3) float array x y z ... (the KITTI layout's
points: the range image's rows are then the device's rings found from their elevations).
Only x, y, z and ring are read: never label, instance or ghost, which are ground truth.
The pose is (4, 4) sensor -> world; the sensor must be still (the pose it was learned at).

Output: ``Boxes`` in the world frame (x y z length width height yaw; z the box centre,
yaw counter-clockwise from +X, ambiguous by pi for vehicles), class by size (vehicle 11,
pedestrian 12, cyclist 18), a confidence in [0, 1].

The steps, a module each:

1. Background (``background.py``): per (ring, azimuth bin) of each sensor's own range
   image, up to three range modes, learned from sweeps of the scene without road users
   (what a deployed unit has after hours) or from frames with traffic.
2. Foreground (``foreground.py``): returns nearer than every mode of their cell, over the
   ground read from the background (``ground.py``).
3. Clustering (``clustering.py``): every sensor's foreground in the world (early
   fusion), DBSCAN on 0.2 m columns, oversized clusters split, fragments merged.
4. Boxing (``boxing.py``, ``box_fit.py``, ``priors.py``): the L-shape heading, extents
   from the points, class by size, partial views grown to the class's size prior
   (at the scene's own types of road users when known: ``types``).
5. Confidence (``confidence.py``): the points and the share of the prior they cover.

Same input, same boxes, bit for bit. scipy and scikit-learn are imported when first
needed."""

from dataclasses import dataclass, field

import numpy as np

from ..detections import Boxes
from . import clustering
from .boxing import boxes as box_groups
from .foreground import SensorBackground, SensorView, foreground, learn_background
from .ground import GroundGrid
from .priors import with_types


@dataclass
class RoadsideDetector:
    """The detector (see the module docstring). Lengths in metres.

    noise_sigma      the device's range noise (the sidecar's effects.noise_sigma_m)
    min_margin       the least foreground margin; the margin is max(min_margin, k_sigma *
                     noise_sigma)
    min_support      share of learning sweeps a cell's farthest mode must be seen in
    persist_support  ... a nearer mode, coming and going (not one long run)
    steady_support   ... a nearer mode, however it came
    max_modes        background range modes kept per cell
    min_neighbours   a foreground pixel needs this many of its 8 neighbours in the range
                     image to be foreground too
    azimuth_res_deg  the range image's azimuth bin (None: the device's step, measured)
    ground_z         the ground's height where the background does not say (None: the
                     median of what it says)
    max_height       foreground higher than this above the ground is not an object
    max_range        foreground from farther than this from its sensor is left out
    voxel            clustering runs on the centroids of voxel x voxel m columns
    eps, min_samples DBSCAN's neighbourhood (m, in x, y) and core size (columns)
    min_points       clusters with fewer points give no box
    merge_*          fragments are merged when their union is at most merge_length long
                     and merge_width wide, the larger is at least merge_min_part long and
                     they are at most merge_gap apart (merge_reach when they touch in a
                     sensor's range image and both are merge_min_part long)
    split_width      a cluster wider than this is more than one vehicle: it is split
    person_gap       a cyclist-sized cluster whose points leave a gap this wide along its
                     length between pedestrian-sized sides is people side by side
    queue_gap        ... a vehicle cluster no type shows whole, between parts of
                     merge_min_part or more: a queue (``clustering.split_at_gaps``)
    min_score        boxes of less confidence (``confidence.py``) are not reported: 0.4
                     asks 14 returns over a whole footprint, or 40 over a fifth of it
    criterion        the heading search's: 'closeness' (L-shape) or 'area'
    pose_tolerance   (m, rad) how far a detection pose may be from the learned one
    types            the scene's own types of road users (``priors.scene_types``: {label
                     id: ((length, width, height, objects), ...)}); None: the built-in
                     priors
    """
    noise_sigma: float = 0.02
    min_margin: float = 0.3
    k_sigma: float = 5.0
    min_support: float = 0.1
    persist_support: float = 0.3
    steady_support: float = 0.9
    min_neighbours: int = 2
    max_modes: int = 3
    azimuth_res_deg: float = None
    ground_z: float = None
    ground_reach: float = 3.0
    max_height: float = 4.5
    max_range: float = 120.0
    voxel: float = 0.2
    eps: float = 0.6
    min_samples: int = 4
    min_points: int = 8
    merge_length: float = 6.2
    merge_width: float = 2.5
    merge_min_part: float = 1.2
    merge_gap: float = 1.5
    merge_reach: float = 4.0
    split_width: float = 3.0
    person_gap: float = 0.1
    queue_gap: float = 0.25
    min_score: float = 0.4
    criterion: str = "closeness"
    pose_tolerance: tuple = (0.05, 0.005)
    types: dict = None
    _grounds: dict = field(default_factory=dict, repr=False, compare=False)

    name = "RLS roadside detector (range-image background, DBSCAN, L-shape boxes)"

    @property
    def margin(self):
        return max(self.min_margin, self.k_sigma * self.noise_sigma)

    @property
    def priors(self):
        """{label: ClassPrior}: the built-in priors with the scene's ``types``."""
        return with_types(self.types)

    def __getstate__(self):  # the ground cache stays behind when sent to a worker
        state = dict(self.__dict__)
        state["_grounds"] = {}
        return state

    # -- the protocol ----------------------------------------------------------------
    def learn(self, sensor, sweeps, pose):
        """``SensorBackground`` of one still sensor from its ``sweeps`` (a few sweeps of
        the scene without road users are best; one sweep cannot tell a glossy facade's
        glass from its ghosts; frames with traffic work as a deployed unit's do over a
        long clip)."""
        return learn_background(self, sensor, sweeps, np.asarray(pose, np.float64))

    def view(self, learned, points, pose):
        """``SensorView``: the foreground of one frame of ``learned``'s sensor."""
        return foreground(self, learned, points, np.asarray(pose, np.float64))

    def detect(self, seen, frame=0):
        """``Boxes`` of one frame from [(SensorBackground, SensorView)] of one or more
        sensors (early fusion: their foregrounds clustered together)."""
        seen = list(seen)
        if not seen:
            return Boxes.empty()
        xyz = np.concatenate([v.xyz for _, v in seen]).reshape(-1, 3)
        pixel = np.concatenate([v.pixel for _, v in seen]).astype(np.int64)
        which = np.concatenate([np.full(len(v.xyz), k, np.int64)
                                for k, (_, v) in enumerate(seen)])
        origins = np.array([b.pose[:3, 3] for b, _ in seen], np.float64)
        columns = np.array([b.model.grid.columns for b, _ in seen], np.int64)
        return self.boxes_of(xyz, which, origins, frame, pixel, columns,
                             self.ground_of([b for b, _ in seen]))

    # -- steps -----------------------------------------------------------------------
    def ground_of(self, backgrounds):
        """The ground grid of these sensors' backgrounds together (kept for the last few
        sets asked for: a study asks for each of its sets over every frame)."""
        if len(backgrounds) == 1:
            return backgrounds[0].ground
        key = tuple(id(b) for b in backgrounds)
        got = self._grounds.get(key)
        if got is None:
            if len(self._grounds) >= 8:
                self._grounds.pop(next(iter(self._grounds)))
            grid = GroundGrid(np.concatenate([b.ground_points for b in backgrounds]),
                              reach=self.ground_reach, default=self.ground_z)
            got = self._grounds[key] = (list(backgrounds), grid)  # the list keeps ids alive
        return got[1]

    def boxes_of(self, xyz, which, origins, frame, pixel, image_columns, ground):
        """Boxes of world-frame foreground points ``xyz`` seen by sensors ``which`` (index
        into ``origins``, (S, 3) sensor positions; ``pixel`` and ``image_columns`` as in
        ``clustering.objects``) over ``ground`` (a ``GroundGrid``)."""
        groups, yaw = clustering.objects(self, xyz, which, pixel, image_columns)
        if not groups:
            return Boxes.empty()
        return box_groups(xyz, which, groups, yaw, np.asarray(origins, np.float64), frame,
                          ground, self.priors, self.min_score)


__all__ = ["RoadsideDetector", "SensorBackground", "SensorView"]
