"""Clustering: a frame's foreground points (every sensor's, in the world) into one
group per object.

Points are gathered in ``voxel`` m square columns of the x-y plane (a car's roof and
sides collapse into its footprint, and a dense near car costs no more than a far one);
scikit-learn's DBSCAN (``eps`` m, ``min_samples`` columns) clusters the columns' centroids:
objects on a road stand side by side, not on top of each other (what is above them was
cut at the detector's ``max_height``). Clusters wider than one vehicle (cars whose points
touch: crossing, side by side) are split by taking out vehicle-sized rectangles
(``box_fit.best_placement``). Fragments of one vehicle (cut by a pole's or a mast arm's
shadow, or by sparse rings across a roof) are merged while their union fits one vehicle
and they are close (``merge_gap``), or touch in a sensor's range image
(``merge_reach``). The parameters ``p`` are the detector's (``RoadsideDetector``).

Every step is a pure function of its input order (DBSCAN's labels follow it; every sort
is stable or on unique keys): the same foreground gives the same groups."""

import numpy as np

from ...errors import InputError
from .box_fit import best_placement, fit_rectangles, inside_rectangle
from .priors import VEHICLE


def objects(p, xyz, which, pixel=None, image_columns=None):
    """(point groups [index arrays into ``xyz``], their headings (G,)) of world-frame
    foreground points ``xyz`` (M, 3) seen by sensors ``which`` (M,) (``pixel``: where
    each is in its sensor's range image, ``image_columns`` (S,) those images' widths, to
    merge fragments that touch there). Clustering, splitting, merging and the heading
    search run on the columns' centroids; the groups hold the points themselves."""
    cen, counts, inverse = columns(p, xyz)
    labels = cluster(p, cen)
    idx = np.flatnonzero(labels >= 0)
    groups = [idx[g] for g in groups_of(labels[idx])] if len(idx) else []
    groups = [g for g in groups if counts[g].sum() >= p.min_points]
    groups, rect = split_oversized(p, cen, counts, groups)
    touching = None
    if pixel is not None and image_columns is not None and len(pixel):
        touching = RangeImageTouch(which, pixel, inverse, image_columns)
    groups, rect = merge_fragments(p, cen, groups, rect, touching)
    if not groups:
        return [], np.zeros(0)
    of_column = np.full(len(cen), -1, np.int64)
    for k, g in enumerate(groups):
        of_column[g] = k
    of_point = of_column[inverse]
    pidx = np.flatnonzero(of_point >= 0)
    return split_at_gaps(p, xyz, [pidx[g] for g in groups_of(of_point[pidx])], rect[:, 4])


def split_at_gaps(p, xyz, groups, yaw):
    """(point groups, headings) with groups that are several objects cut apart where
    their points, along the group's length, leave a gap (the widest qualifying gap, then
    each side again; the parts keep the group's heading):

    - People abreast. SUMO's pedestrians walk in stripes 0.64 m apart: two abreast leave
      0.16 m between their shoulders, which DBSCAN's 0.6 m on 0.2 m columns bridges into
      one cyclist-sized cluster. A group no longer than the largest cyclist and no wider
      is cut at a gap of at least ``person_gap`` whose sides are no longer than the
      largest pedestrian (a bicycle and its rider leave no such gap).
    - A queue. Cars standing at a red light can stop 0.4 m apart, which clustering
      bridges into one long vehicle. With the scene's types known, a group no type of
      vehicle shows whole and longer than the commonest one is cut at a gap of at least
      ``queue_gap`` whose sides are ``merge_min_part`` long or more (a bus, a van or a
      truck shows its type whole and is never cut; without the scene's types, a truck's
      cab and trailer could be taken for a queue: nothing is cut).

    Every side holds ``min_points`` returns or more."""
    from .priors import CYCLIST, PEDESTRIAN, SIZE_MARGIN, VEHICLE, shown_whole

    ped, cyc, veh = p.priors[PEDESTRIAN], p.priors[CYCLIST], p.priors[VEHICLE]
    common = max(veh.kinds, key=lambda k: k[3])
    out_groups, out_yaw = [], []
    work = list(zip(groups, yaw))
    while work:
        g, y = work.pop(0)
        u = xyz[g, 0] * np.cos(y) + xyz[g, 1] * np.sin(y)
        v = -xyz[g, 0] * np.sin(y) + xyz[g, 1] * np.cos(y)
        along, across = (u, v) if np.ptp(u) >= np.ptp(v) else (v, u)
        length, width = np.ptp(along), np.ptp(across)
        rule = None
        if len(g) >= 2 * p.min_points:
            if ped.max_length < length <= cyc.max_length and width <= cyc.max_width:
                rule = (p.person_gap, 0.0, ped.max_length, max(ped.max_length, cyc.max_length))
            elif veh.types and length > max(common[:2]) + SIZE_MARGIN \
                    and width <= veh.max_width:
                if shown_whole(veh, length, width, np.ptp(xyz[g, 2])) is None:
                    rule = (p.queue_gap, p.merge_min_part, np.inf, np.inf)
        cut = None if rule is None else _widest_gap(along, p.min_points, *rule)
        if cut is None:
            out_groups.append(g)
            out_yaw.append(y)
            continue
        order = np.argsort(along, kind="stable")
        out_groups.append(np.sort(g[order[:cut + 1]]))
        out_yaw.append(y)
        work.insert(0, (np.sort(g[order[cut + 1:]]), y))  # the rest may hold another
    return out_groups, np.asarray(out_yaw, np.float64)


def _widest_gap(along, min_points, min_gap, min_side, max_low, max_high):
    """The index (in ``along``'s sorted order) after which the widest gap of at least
    ``min_gap`` lies whose low side is ``min_side`` to ``max_low`` long, whose high
    side is ``min_side`` to ``max_high`` long, each of ``min_points`` or more; None."""
    a = np.sort(along, kind="stable")
    gaps = np.diff(a)
    n_low = np.arange(1, len(a))
    low, high = a[n_low - 1] - a[0], a[-1] - a[n_low]
    ok = (gaps >= min_gap) & (n_low >= min_points) & (len(a) - n_low >= min_points) & \
         (low >= min_side) & (low <= max_low) & (high >= min_side) & (high <= max_high)
    if not ok.any():
        return None
    return int(np.flatnonzero(ok)[np.argmax(gaps[ok])])


def columns(p, xyz):
    """(centroids (V, 2), returns (V,), column of each point (M,)): world points
    ``xyz`` gathered in ``voxel`` m square columns of the x-y plane, in key order."""
    if not len(xyz):
        return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    ij = np.floor(xyz[:, :2] / p.voxel).astype(np.int64)
    ij -= ij.min(0)
    if (ij >= 1 << 31).any():
        raise InputError("the foreground spans too far: check the sensor poses")
    key = (ij[:, 0] << 31) | ij[:, 1]
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.stack([np.bincount(inverse, xyz[:, i], len(counts)) for i in range(2)], 1)
    return sums / counts[:, None], counts, inverse


def cluster(p, xy):
    """(V,) DBSCAN label of each x-y point (here: column centroid; -1: noise)."""
    if len(xy) < p.min_samples:
        return np.full(len(xy), -1, np.int64)
    from sklearn.cluster import DBSCAN

    return DBSCAN(eps=p.eps, min_samples=p.min_samples,
                  algorithm="kd_tree").fit_predict(xy).astype(np.int64)


def fit(p, xy, groups):
    if not groups:
        return np.zeros((0, 5))
    sizes = np.array([len(g) for g in groups], np.int64)
    return fit_rectangles(xy[np.concatenate(groups)], sizes, p.criterion)


def split_oversized(p, xy, counts, groups, max_parts=8):
    """Clusters wider than one vehicle (cars side by side, or crossing, whose points
    touch) are split: the vehicle-sized rectangle that covers most of the cluster
    (``box_fit.best_placement``) is taken out with the columns within 0.25 m of it,
    the rest is clustered again, and what is still too wide is split again.
    Returns (groups, their rectangles), the groups in order of their first column."""
    rect = fit(p, xy, groups)
    out, work = [], []
    for g, r in zip(groups, rect):
        (work if r[3] > p.split_width else out).append(g)
    if not work:
        return groups, rect
    prior = p.priors[VEHICLE].size
    parts = 0
    while work:
        g = work.pop(0)
        if parts >= max_parts * len(groups):
            out.append(g)
            continue
        _, cx, cy, yaw = best_placement(xy[g], prior[:2])
        inside = inside_rectangle(xy[g], cx, cy, prior[0], prior[1], yaw, grow=0.25)
        if counts[g[inside]].sum() < p.min_points or inside.all():
            out.append(g)
            continue
        parts += 1
        out.append(g[inside])
        rest = g[~inside]
        sub = cluster(p, xy[rest])
        pieces = [rest[sub >= 0][q] for q in groups_of(sub[sub >= 0])]
        pieces = [q for q in pieces if counts[q].sum() >= p.min_points]
        for q, r in zip(pieces, fit(p, xy, pieces)):
            (work if r[3] > p.split_width else out).append(q)
    out = [np.sort(g) for g in out]
    out.sort(key=lambda g: int(g[0]))
    return out, fit(p, xy, out)


def merge_fragments(p, xy, groups, rect, touching=None, rounds=4):
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
        pair_ok = np.maximum(rect[i, 2], rect[j, 2]) >= p.merge_min_part
        pair_ok &= (rect[i, 2] <= p.merge_length) & (rect[j, 2] <= p.merge_length)
        i, j = i[pair_ok], j[pair_ok]
        if not len(i):
            break
        union = fit(p, xy, [np.concatenate([groups[a], groups[b]]) for a, b in zip(i, j)])
        fits = (union[:, 2] <= p.merge_length) & (union[:, 3] <= p.merge_width)
        i, j, union = i[fits], j[fits], union[fits]
        near = np.zeros(len(i), bool)
        for k, (a, b) in enumerate(zip(i, j)):
            key = (int(groups[a][0]), len(groups[a]), int(groups[b][0]), len(groups[b]))
            if key not in linked:  # pairs of unchanged groups are judged once
                apart = gap(xy[groups[a]], xy[groups[b]])
                # across a wider gap both must be long (a ring across a roof spans
                # the car): a pedestrian seen behind a cyclist touches it too
                linked[key] = apart <= p.merge_gap or (
                    touching is not None and apart <= p.merge_reach
                    and min(rect[a, 2], rect[b, 2]) >= p.merge_min_part
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


class RangeImageTouch:
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


def gap(a, b, cap=400):
    """The least distance between two sets of x-y points (each thinned to ``cap`` points
    by a fixed stride)."""
    a = a[::max(1, len(a) // cap)]
    b = b[::max(1, len(b) // cap)]
    d = np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=2)
    return float(np.sqrt(d.min()))


def groups_of(labels):
    """Indices of each label (>= 0), in label order, each ascending."""
    order = np.argsort(labels, kind="stable")
    sl = labels[order]
    cut = np.flatnonzero(np.diff(sl)) + 1
    return [g for g in np.split(order, cut)]
