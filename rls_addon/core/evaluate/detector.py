"""RLS's built-in detector for still roadside LiDARs: background subtraction, DBSCAN, an
oriented box per object. CPU only, deterministic, nothing trained, so a scene can be
simulated and scored anywhere.

    det = RoadsideDetector(noise_sigma=0.02)
    det.learn({"L1": frames_of_L1, "L2": frames_of_L2}, {"L1": pose1, "L2": pose2})
    boxes = det.detect({"L1": points1, "L2": points2}, {"L1": pose1, "L2": pose2}, frame=7)

Inputs, per sensor (a dict by sensor name, or a sequence in a fixed order):

points   a frame's returns in the SENSOR frame (x forward, y left, z up; metres), as RLS
         writes them with ``frame_space = sensor`` (``io.cloud.read_cloud``) or as a
         device reports them: a structured array with x, y, z and, best, ring; or an
         (N, >=3) float array x y z ... (the KITTI layout's points/NNNNNN.npy: the range
         image's rows are then the device's rings found from their elevations). Only x,
         y, z and ring are read: never label, instance or ghost, which are ground truth.
pose     (4, 4) sensor -> world (the sidecar's ``sensor_to_world``). The sensor must be
         still: the same pose when learning and detecting.

Output: ``Boxes`` in the world frame (x y z length width height yaw; z the box centre,
yaw counter-clockwise from +X, ambiguous by pi for vehicles), class by size (vehicle 11,
pedestrian 12, cyclist 18), a score in [0, 1].

The steps, and why:

1. Background (``background.py``): per (ring, azimuth bin) of each sensor's own range
   image, up to three range modes. The farthest mode seen in >= 10% of the learning
   frames is background; a nearer one when seen in >= 90%, or in >= 30% coming and going
   (a glossy facade's glass/ghost flip), not in one long run (a car that stood and left).
   Foreground: nearer than every kept mode by ``max(0.3 m, 5 sigma)``, and not alone in
   the range image (2 of 8 neighbours). Returns in cells that never had a background are
   kept when plausibly an object (height above the ground and distance, below).
2. Ground (``GroundGrid``): the lowest background return in each 1 m cell of the world's
   x-y plane, spread to the lowest within ``ground_reach``: the road under a car is
   hidden by the car but not the road around it. Foreground points are kept from 0.3 m
   below to ``max_height`` above it (a bird, a false return from fog high up: no).
3. Early fusion: every sensor's foreground, in the world frame, is clustered together by
   scikit-learn's DBSCAN (``eps`` 0.6 m) on the centroids of 0.2 m x-y columns: objects
   on a road stand side by side, not on top of each other (and what is above them was
   cut at ``max_height``); a car's roof and sides collapse into its footprint, so a near
   car of thousands of returns costs no more than a far one.
4. Clusters wider than one vehicle (cars whose points touch: crossing, side by side) are
   split by taking out vehicle-sized rectangles (``box_fit.best_placement``). Fragments
   of one vehicle (cut by a pole's or a mast arm's shadow, or by sparse rings across a
   roof) are merged while their union fits one vehicle and they are close (1.5 m), or
   touch in a sensor's range image (4 m).
5. Boxes (``box_fit.py``): the heading minimising the L-shape closeness criterion (it
   does not mind whether one side, two or the roof is seen); extents from the points;
   top from the highest point, bottom from the lowest (the ground when the lower part is
   hidden). Class by size. A vehicle or cyclist whose visible extent is partial is grown
   to its class's size prior (vehicle 4.5 x 1.8 m) away from the sensors that saw it (the
   far side is hidden by the object), or towards a sensor that saw it behind another
   cluster (the occluder hides the near side).
6. Score: ``n / (n + 20)`` of the point count times how much of the prior's footprint
   the points cover (``0.5 + 0.5 * min(1, seen area / prior area)``).

Same input, same boxes, bit for bit: every step is a pure function of its input order
(DBSCAN's labels follow the input order; every sort is stable or on unique keys).
scipy and scikit-learn are imported when first needed.
"""

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..labels import NAME_TO_ID
from .background import BackgroundModel, sensor_xyz_ring
from .box_fit import (best_placement, fit_rectangles, inside_rectangle, rectangles_along,
                      wrap_half_turn)
from .detections import Boxes

VEHICLE, PEDESTRIAN, CYCLIST = (NAME_TO_ID[n] for n in ("vehicle", "pedestrian", "cyclist"))


@dataclass(frozen=True)
class ClassPrior:
    """A class's typical size (length, width, height in m) that partial views are grown
    to, and the largest length and width one object of the class can have."""
    label: int
    size: tuple
    max_length: float
    max_width: float


PRIORS = {
    VEHICLE: ClassPrior(VEHICLE, (4.5, 1.8, 1.6), 18.0, 3.2),
    CYCLIST: ClassPrior(CYCLIST, (1.8, 0.7, 1.7), 2.4, 1.1),
    PEDESTRIAN: ClassPrior(PEDESTRIAN, (0.7, 0.7, 1.75), 1.3, 1.3),
}


class GroundGrid:
    """The ground's height under the scene from background returns (world frame): the
    lowest return in each ``cell`` m square, then the lowest within ``reach`` m (a square
    window), so a cell covered by a car, a roof or a wall reads the road next to it.
    ``at(xy)`` is NaN where nothing was seen within reach."""

    def __init__(self, xyz, cell=1.0, reach=3.0, bounds=None):
        xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
        xyz = xyz[np.isfinite(xyz).all(axis=1)]
        self.cell = float(cell)
        if bounds is not None:
            (x0, y0), (x1, y1) = bounds
            inside = (xyz[:, 0] >= x0) & (xyz[:, 0] < x1) & (xyz[:, 1] >= y0) & (xyz[:, 1] < y1)
            xyz = xyz[inside]
        if not len(xyz):
            self.origin, self.z = np.zeros(2), np.full((1, 1), np.nan)
            return
        self.origin = np.floor(xyz[:, :2].min(0) / self.cell) * self.cell
        ij = np.floor((xyz[:, :2] - self.origin) / self.cell).astype(np.int64)
        shape = tuple(ij.max(0) + 1)
        z = np.full(shape, np.inf)
        np.minimum.at(z, (ij[:, 0], ij[:, 1]), xyz[:, 2])
        k = int(round(reach / self.cell))
        if k > 0:
            from scipy.ndimage import minimum_filter

            z = minimum_filter(z, size=2 * k + 1, mode="constant", cval=np.inf)
        self.z = np.where(np.isfinite(z), z, np.nan)

    def at(self, xy):
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        ij = np.floor((xy - self.origin) / self.cell).astype(np.int64)
        ok = (ij >= 0).all(axis=1) & (ij[:, 0] < self.z.shape[0]) & (ij[:, 1] < self.z.shape[1])
        out = np.full(len(xy), np.nan)
        out[ok] = self.z[ij[ok, 0], ij[ok, 1]]
        return out


@dataclass
class SensorBackground:
    model: BackgroundModel
    pose: np.ndarray


@dataclass
class RoadsideDetector:
    """The detector (see the module docstring). Lengths in metres.

    noise_sigma      the device's range noise (the sidecar's effects.noise_sigma_m)
    min_margin       the least foreground margin; the margin is max(min_margin, k_sigma *
                     noise_sigma)
    min_support      share of learning frames a cell's farthest mode must be seen in
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
    criterion        the heading search's: 'closeness' (L-shape) or 'area'
    pose_tolerance   (m, rad) how far a detection pose may be from the learned one
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
    criterion: str = "closeness"
    pose_tolerance: tuple = (0.05, 0.005)
    backgrounds: dict = field(default_factory=dict, repr=False)
    ground: GroundGrid = field(default=None, repr=False)

    @property
    def margin(self):
        return max(self.min_margin, self.k_sigma * self.noise_sigma)

    # -- learning --------------------------------------------------------------------
    def learn(self, frames_per_sensor, sensor_poses):
        """Learn each sensor's background from its frames: a list of point arrays (see the
        module docstring), with traffic or without (a few traffic-free frames are best:
        one frame cannot tell a glossy facade's glass from its ghosts). The ground grid
        is made from every sensor's background. ``frames_per_sensor`` and
        ``sensor_poses`` are dicts by sensor name or sequences in one order. Returns
        self."""
        frames, poses = _by_sensor(frames_per_sensor, sensor_poses)
        self.backgrounds = {}
        for key in frames:
            fr = frames[key]
            if isinstance(fr, np.ndarray) and (fr.dtype.names or fr.ndim == 2):
                fr = [fr]  # one frame given bare
            model = BackgroundModel.learn(list(fr), margin=self.margin,
                                          min_support=self.min_support,
                                          persist_support=self.persist_support,
                                          steady_support=self.steady_support,
                                          max_modes=self.max_modes,
                                          azimuth_res_deg=self.azimuth_res_deg)
            self.backgrounds[key] = SensorBackground(model, poses[key])
        self._make_ground()
        return self

    def _make_ground(self):
        """The ground grid from every sensor's background (within ``max_range``)."""
        ground = []
        for bg in self.backgrounds.values():
            pts = bg.model.background_xyz()
            pts = pts[np.linalg.norm(pts, axis=1) <= self.max_range]
            ground.append(pts @ bg.pose[:3, :3].T + bg.pose[:3, 3])
        self.ground = GroundGrid(np.concatenate(ground) if ground else np.zeros((0, 3)),
                                 reach=self.ground_reach)

    def union(self, others):
        """A detector of this one's sensors and those of ``others`` (learned apart, with
        the same parameters, each of other sensors): their backgrounds side by side
        and the ground grid of all of them, what learning them together gives. A
        placement study learns each candidate once and fuses any set of them."""
        out = dataclasses.replace(self, backgrounds=dict(self.backgrounds), ground=None)
        for det in others:
            if det.margin != self.margin or det.max_range != self.max_range:
                raise InputError("detectors of other parameters cannot be fused")
            for key, bg in det.backgrounds.items():
                if key in out.backgrounds:
                    raise InputError(f"sensor {key!r} is in two of the detectors to fuse")
                out.backgrounds[key] = bg
        out._make_ground()
        return out

    def _ground_at(self, xy):
        z = self.ground.at(xy) if self.ground is not None else np.full(len(xy), np.nan)
        return np.where(np.isnan(z), self._ground_default(), z)

    def _ground_default(self):
        if self.ground_z is not None:
            return float(self.ground_z)
        g = self.ground.z if self.ground is not None else np.array([np.nan])
        g = g[np.isfinite(g)]
        return float(np.median(g)) if len(g) else 0.0

    def _check_still(self, key, pose):
        learned = self.backgrounds[key].pose
        moved = np.linalg.norm(pose[:3, 3] - learned[:3, 3])
        turn = np.arccos(np.clip((np.trace(pose[:3, :3].T @ learned[:3, :3]) - 1) / 2, -1, 1))
        if moved > self.pose_tolerance[0] or turn > self.pose_tolerance[1]:
            raise InputError(f"sensor {key!r} is {moved:.3f} m and {np.degrees(turn):.2f} deg "
                             "from where its background was learned: the detector is for "
                             "still sensors (learn again for the new pose)")

    # -- detection -------------------------------------------------------------------
    def foreground(self, points_per_sensor, sensor_poses):
        """(world xyz (M, 3), sensor index (M,), pixel (M,)) of the frame's foreground,
        every sensor's together (early fusion), in the order of the sensors and their
        points; a pixel is where the point is in its sensor's range image
        (``RangeImageGrid.pixel_of``: elevation rank << 32 | column; -1 unknown)."""
        if not self.backgrounds:
            raise InputError("the detector has no background: call learn() first")
        points, poses = _by_sensor(points_per_sensor, sensor_poses)
        out, which, pixel = [], [], []
        for k, key in enumerate(points):
            if key not in self.backgrounds:
                raise InputError(f"no background was learned for sensor {key!r}")
            model = self.backgrounds[key].model
            self._check_still(key, poses[key])
            fg, empty, xyz, cell = model.foreground(points[key], self.min_neighbours)
            cand = fg | empty
            local = xyz[cand]
            pose = poses[key]
            w = local @ pose[:3, :3].T + pose[:3, 3]
            h = w[:, 2] - self._ground_at(w[:, :2])
            keep = (h > -0.3) & (h < self.max_height) & \
                   (np.linalg.norm(local, axis=1) <= self.max_range)
            out.append(w[keep])
            which.append(np.full(int(keep.sum()), k, np.int64))
            pixel.append(model.grid.pixel_of(cell[cand][keep]))
        if not out:
            return np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(out), np.concatenate(which), np.concatenate(pixel)

    def detect(self, points_per_sensor, sensor_poses, frame=0):
        """``Boxes`` of one frame (see the module docstring), all in ``frame``."""
        xyz, which, pixel = self.foreground(points_per_sensor, sensor_poses)
        points, poses = _by_sensor(points_per_sensor, sensor_poses)
        origins = np.array([np.asarray(p, np.float64)[:3, 3] for p in poses.values()]) \
            if poses else np.zeros((0, 3))
        columns = np.array([self.backgrounds[k].model.grid.columns for k in points], np.int64)
        return self.boxes_of(xyz, which, origins, frame, pixel, columns)

    def columns(self, xyz):
        """(centroids (V, 2), returns (V,), column of each point (M,)): world points
        ``xyz`` gathered in ``voxel`` m square columns of the x-y plane, in key order."""
        if not len(xyz):
            return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64)
        ij = np.floor(xyz[:, :2] / self.voxel).astype(np.int64)
        ij -= ij.min(0)
        if (ij >= 1 << 31).any():
            raise InputError("the foreground spans too far: check the sensor poses")
        key = (ij[:, 0] << 31) | ij[:, 1]
        _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        inverse = inverse.reshape(-1)
        sums = np.stack([np.bincount(inverse, xyz[:, i], len(counts)) for i in range(2)], 1)
        return sums / counts[:, None], counts, inverse

    def cluster(self, xy):
        """(V,) DBSCAN label of each x-y point (here: column centroid; -1: noise)."""
        if len(xy) < self.min_samples:
            return np.full(len(xy), -1, np.int64)
        from sklearn.cluster import DBSCAN

        return DBSCAN(eps=self.eps, min_samples=self.min_samples,
                      algorithm="kd_tree").fit_predict(xy).astype(np.int64)

    def boxes_of(self, xyz, which, origins, frame=0, pixel=None, image_columns=None):
        """Boxes of world-frame foreground points ``xyz`` seen by sensors ``which`` (index
        into ``origins``, (S, 3) sensor positions; ``pixel``: where each is in its sensor's
        range image, ``image_columns`` (S,) those images' widths, to merge fragments that
        touch there). Clustering, splitting, merging and the
        heading search run on the centroids of ``voxel`` m columns (a car's roof and sides
        collapse into its footprint, and a dense near car costs no more than a far one);
        extents and heights come from the returns themselves."""
        cen, counts, inverse = self.columns(xyz)
        labels = self.cluster(cen)
        idx = np.flatnonzero(labels >= 0)
        groups = [idx[g] for g in _groups(labels[idx])] if len(idx) else []
        groups = [g for g in groups if counts[g].sum() >= self.min_points]
        groups, rect = self._split_oversized(cen, counts, groups)
        touching = None
        if pixel is not None and image_columns is not None and len(pixel):
            touching = _RangeImageTouch(which, pixel, inverse, image_columns)
        groups, rect = self._merge_fragments(cen, groups, rect, touching)
        if not groups:
            return Boxes.empty()
        of_column = np.full(len(cen), -1, np.int64)
        for k, g in enumerate(groups):
            of_column[g] = k
        of_point = of_column[inverse]
        pidx = np.flatnonzero(of_point >= 0)
        point_groups = [pidx[g] for g in _groups(of_point[pidx])]
        return self._boxes(xyz, which, point_groups, rect[:, 4],
                           np.asarray(origins, np.float64), frame)

    # -- steps -----------------------------------------------------------------------
    def _fit(self, xy, groups):
        if not groups:
            return np.zeros((0, 5))
        sizes = np.array([len(g) for g in groups], np.int64)
        return fit_rectangles(xy[np.concatenate(groups)], sizes, self.criterion)

    def _split_oversized(self, xy, counts, groups, max_parts=8):
        """Clusters wider than one vehicle (cars side by side, or crossing, whose points
        touch) are split: the vehicle-sized rectangle that covers most of the cluster
        (``box_fit.best_placement``) is taken out with the columns within 0.25 m of it,
        the rest is clustered again, and what is still too wide is split again.
        Returns (groups, their rectangles), the groups in order of their first column."""
        rect = self._fit(xy, groups)
        out, work = [], []
        for g, r in zip(groups, rect):
            (work if r[3] > self.split_width else out).append(g)
        if not work:
            return groups, rect
        prior = PRIORS[VEHICLE].size
        parts = 0
        while work:
            g = work.pop(0)
            if parts >= max_parts * len(groups):
                out.append(g)
                continue
            _, cx, cy, yaw = best_placement(xy[g], prior[:2])
            inside = inside_rectangle(xy[g], cx, cy, prior[0], prior[1], yaw, grow=0.25)
            if counts[g[inside]].sum() < self.min_points or inside.all():
                out.append(g)
                continue
            parts += 1
            out.append(g[inside])
            rest = g[~inside]
            sub = self.cluster(xy[rest])
            pieces = [rest[sub >= 0][p] for p in _groups(sub[sub >= 0])]
            pieces = [p for p in pieces if counts[p].sum() >= self.min_points]
            for p, r in zip(pieces, self._fit(xy, pieces)):
                (work if r[3] > self.split_width else out).append(p)
        out = [np.sort(g) for g in out]
        out.sort(key=lambda g: int(g[0]))
        return out, self._fit(xy, out)

    def _merge_fragments(self, xy, groups, rect, touching=None, rounds=4):
        """Merge pairs of clusters whose union is no larger than one vehicle and that are
        at most ``merge_gap`` apart, or at most ``merge_reach`` apart and touching in a
        sensor's range image (neighbouring rings: a sparse device's rings cross a car's
        roof metres apart, with nothing seen between them), smallest union first, until
        nothing merges; each cluster merges once per round.
        Returns (groups, their rectangles)."""
        linked = {}
        for _ in range(rounds):
            if len(groups) < 2:
                break
            centre, reach = rect[:, :2], rect[:, 2] / 2
            d = np.linalg.norm(centre[:, None] - centre[None], axis=2)
            i, j = np.nonzero(np.triu(d <= reach[:, None] + reach[None] + 1.5, 1))
            pair_ok = np.maximum(rect[i, 2], rect[j, 2]) >= self.merge_min_part
            pair_ok &= (rect[i, 2] <= self.merge_length) & (rect[j, 2] <= self.merge_length)
            i, j = i[pair_ok], j[pair_ok]
            if not len(i):
                break
            union = self._fit(xy, [np.concatenate([groups[a], groups[b]]) for a, b in zip(i, j)])
            fits = (union[:, 2] <= self.merge_length) & (union[:, 3] <= self.merge_width)
            i, j, union = i[fits], j[fits], union[fits]
            near = np.zeros(len(i), bool)
            for k, (a, b) in enumerate(zip(i, j)):
                key = (int(groups[a][0]), len(groups[a]), int(groups[b][0]), len(groups[b]))
                if key not in linked:  # pairs of unchanged groups are judged once
                    gap = _gap(xy[groups[a]], xy[groups[b]])
                    # across a wider gap both must be long (a ring across a roof spans
                    # the car): a pedestrian seen behind a cyclist touches it too
                    linked[key] = gap <= self.merge_gap or (
                        touching is not None and gap <= self.merge_reach
                        and min(rect[a, 2], rect[b, 2]) >= self.merge_min_part
                        and touching(groups[a], groups[b]))
                near[k] = linked[key]
            if not near.any():
                break
            i, j, union = i[near], j[near], union[near]
            order = np.lexsort((j, i, union[:, 2] * union[:, 3]))
            used = np.zeros(len(groups), bool)
            merged, merged_rect = [], []
            for k in order:
                a, b = i[k], j[k]
                if used[a] or used[b]:
                    continue
                used[a] = used[b] = True
                merged.append(np.sort(np.concatenate([groups[a], groups[b]])))
                merged_rect.append(union[k])
            keep = np.flatnonzero(~used)
            groups = [groups[k] for k in keep] + merged
            rect = np.concatenate([rect[keep], np.array(merged_rect)])
            order = sorted(range(len(groups)), key=lambda k: int(groups[k][0]))
            groups, rect = [groups[k] for k in order], rect[order]
        return groups, rect

    def _boxes(self, xyz, which, groups, yaw, origins, frame):
        n = len(groups)
        sizes = np.array([len(g) for g in groups], np.int64)
        idx = np.concatenate(groups)
        rect = rectangles_along(xyz[idx, :2], sizes, yaw)
        starts = np.r_[0, np.cumsum(sizes)[:-1]]
        z = xyz[idx, 2]
        top = np.maximum.reduceat(z, starts)
        low = np.minimum.reduceat(z, starts)
        ground = self._ground_at(rect[:, :2])
        height = top - ground
        label = _classify(rect[:, 2], rect[:, 3], height)
        keep = label > 0
        # which sensors saw each cluster: the side of the box each looks from
        seen_by = np.zeros((n, max(len(origins), 1)), bool)
        seen_by[np.repeat(np.arange(n), sizes), which[idx]] = True
        behind = _occluded(xyz[idx, :2], which[idx], sizes, origins)
        box = np.zeros((n, 7))
        area_share = np.ones(n)
        for k in np.flatnonzero(keep):
            prior = PRIORS[label[k]]
            cx, cy, L, W, yk = rect[k]
            eyes = origins[seen_by[k, :len(origins)], :2]
            if label[k] != PEDESTRIAN:
                cx, cy, L, W = _grow(cx, cy, L, W, yk, prior.size[0], prior.size[1], eyes,
                                     behind[k, seen_by[k, :len(origins)]])
            else:
                L, W = max(L, prior.size[0] * 0.6), max(W, prior.size[1] * 0.6)
            area_share[k] = min(1.0, rect[k, 2] * rect[k, 3] / (prior.size[0] * prior.size[1]))
            # bottom: the lowest point, or the ground when the lower part is hidden
            bottom = low[k]
            if bottom - ground[k] > 0.5:
                bottom = max(ground[k], top[k] - prior.size[2])
            h = max(top[k] - bottom, 0.3)
            box[k] = (cx, cy, bottom + h / 2, L, W, h, wrap_half_turn(yk))
        score = sizes / (sizes + 20.0) * (0.5 + 0.5 * area_share)
        sel = np.flatnonzero(keep)
        return Boxes(np.full(len(sel), frame), box[sel], label[sel],
                     np.clip(score[sel], 0.0, 1.0))


def _classify(length, width, height):
    """Class by size: a vehicle is longer than 2.4 m or wider than 1.1 m; a cyclist is
    1.3-2.4 m long and narrow; a pedestrian is small on the ground; all at least 0.5 m
    tall above the ground and no larger than the largest vehicle. 0 is no object."""
    label = np.zeros(len(length), np.int64)
    tall = height >= 0.5
    label[tall & (length <= PRIORS[PEDESTRIAN].max_length) &
          (width <= PRIORS[CYCLIST].max_width)] = PEDESTRIAN
    label[tall & (length > PRIORS[PEDESTRIAN].max_length) &
          (length <= PRIORS[CYCLIST].max_length) & (width <= PRIORS[CYCLIST].max_width)] = CYCLIST
    veh = tall & ((length > PRIORS[CYCLIST].max_length) | (width > PRIORS[CYCLIST].max_width))
    veh &= (length <= PRIORS[VEHICLE].max_length) & (width <= PRIORS[VEHICLE].max_width)
    label[veh] = VEHICLE
    return label


def _grow(cx, cy, L, W, yaw, L0, W0, eyes, behind=None):
    """The rectangle grown to at least L0 x W0, each axis away from the sensors that saw
    it (a sensor sees an object's near side; its far side is hidden by the object
    itself), or towards a sensor that saw it behind another object (``behind``: the
    occluder hides the near side, the far side is what shows); along an axis whose both
    ends are seen (or neither), about its middle."""
    c, s = np.cos(yaw), np.sin(yaw)
    out = []
    for axis, (ext, want) in enumerate(((L, L0), (W, W0))):
        if ext >= want:
            out.append((0.0, ext))
            continue
        u = np.array([c, s]) if axis == 0 else np.array([-s, c])
        if len(eyes):
            pos = (eyes - (cx, cy)) @ u  # where each sensor is along this axis
            if behind is not None:
                pos = np.where(behind, -pos, pos)  # an occluded sensor sees the far side
            low_side = bool((pos < -ext / 2).any())
            high_side = bool((pos > ext / 2).any())
        else:
            low_side = high_side = False
        grow = want - ext
        if low_side and not high_side:  # the low end is the seen one: grow upwards
            shift = grow / 2
        elif high_side and not low_side:
            shift = -grow / 2
        else:
            shift = 0.0
        out.append((shift, want))
    (su, L), (sv, W) = out
    cx += su * c - sv * s
    cy += su * s + sv * c
    return cx, cy, L, W


class _RangeImageTouch:
    """Whether two groups of columns hold returns that neighbour each other in a sensor's
    range image: the same sensor, elevation ranks at most one apart, columns at most two
    apart (with the wrap at 360 degrees)."""

    def __init__(self, which, pixel, inverse, image_columns):
        ok = pixel >= 0
        key = np.where(ok, (which << 48) | pixel, -1)
        order = np.argsort(inverse, kind="stable")
        self.key = key[order]  # by column
        self.start = np.searchsorted(inverse[order], np.arange(inverse.max() + 2))
        self.ncol = np.asarray(image_columns, np.int64)

    def _keys(self, cols):
        lo, hi = self.start[cols], self.start[np.asarray(cols) + 1]
        n = hi - lo
        idx = np.repeat(lo - np.r_[0, np.cumsum(n)[:-1]], n) + np.arange(n.sum())
        return self.key[idx]

    def __call__(self, cols_a, cols_b):
        ka, kb = self._keys(cols_a), self._keys(cols_b)
        ka, kb = ka[ka >= 0], kb[kb >= 0]
        if not len(ka) or not len(kb):
            return False
        s, rank, col = ka >> 48, (ka >> 32) & 0xFFFF, ka & 0xFFFFFFFF
        for dr in (-1, 0, 1):
            r = rank + dr
            for dc in (-2, -1, 0, 1, 2):
                c = (col + dc) % self.ncol[s]
                if np.isin((s << 48) | (r << 32) | c, kb).any():
                    return True
        return False


def _gap(a, b, cap=400):
    """The least distance between two sets of x-y points (each thinned to ``cap`` points
    by a fixed stride)."""
    a = a[::max(1, len(a) // cap)]
    b = b[::max(1, len(b) // cap)]
    d = np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=2)
    return float(np.sqrt(d.min()))


def _occluded(xy, which, sizes, origins, min_overlap=0.3):
    """(G, S) bool: group k is seen by sensor s behind another group: one whose azimuth
    interval from s (its points', seen by s) covers at least ``min_overlap`` of k's and
    whose nearest point is nearer to s. Such a group shows s its far side."""
    G, S = len(sizes), len(origins)
    out = np.zeros((G, S), bool)
    if G < 2:
        return out
    g = np.repeat(np.arange(G), sizes)
    for s_ in range(S):
        mine = which == s_
        if not mine.any():
            continue
        d = xy[mine] - origins[s_, :2]
        gk = g[mine]
        present = np.bincount(gk, minlength=G) > 0
        az = np.arctan2(d[:, 1], d[:, 0])
        r = np.hypot(d[:, 0], d[:, 1])
        # each group's interval about its mean direction (no wrap within an object)
        cx = np.bincount(gk, np.cos(az), G)
        cy = np.bincount(gk, np.sin(az), G)
        mid = np.arctan2(cy, cx)
        rel = np.angle(np.exp(1j * (az - mid[gk])))
        lo = np.full(G, np.inf)
        hi = np.full(G, -np.inf)
        rmin = np.full(G, np.inf)
        np.minimum.at(lo, gk, rel)
        np.maximum.at(hi, gk, rel)
        np.minimum.at(rmin, gk, r)
        shift = np.angle(np.exp(1j * (mid[None, :] - mid[:, None])))  # j's mid seen from k's
        jlo, jhi = lo[None, :] + shift, hi[None, :] + shift
        overlap = np.clip(np.minimum(hi[:, None], jhi) - np.maximum(lo[:, None], jlo), 0, None)
        span = np.maximum(hi - lo, 1e-9)[:, None]
        front = (overlap / span >= min_overlap) & (rmin[None, :] < rmin[:, None])
        front &= present[:, None] & present[None, :]
        np.fill_diagonal(front, False)
        out[:, s_] = front.any(axis=1)
    return out


def _groups(labels):
    """Indices of each label (>= 0), in label order, each ascending."""
    order = np.argsort(labels, kind="stable")
    sl = labels[order]
    cut = np.flatnonzero(np.diff(sl)) + 1
    return [g for g in np.split(order, cut)]


def _by_sensor(points, poses):
    """(points, poses) as dicts with the same keys, in the given order."""
    if isinstance(points, dict):
        if not isinstance(poses, dict):
            poses = dict(zip(points, poses))
    else:
        points = {k: p for k, p in enumerate(points)}
        poses = {k: p for k, p in enumerate(poses)} if not isinstance(poses, dict) else poses
    missing = [k for k in points if k not in poses]
    if missing:
        raise InputError(f"no sensor pose for {missing}")
    out = {}
    for k in points:
        m = np.asarray(poses[k], np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise InputError(f"sensor {k!r}: the pose must be a finite 4x4 matrix")
        out[k] = m
    return points, out


__all__ = ["RoadsideDetector", "GroundGrid", "PRIORS", "sensor_xyz_ring"]
