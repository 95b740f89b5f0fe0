"""Placements scored with the traffic in view: how well candidates (and sets of them)
see the vehicles that drive through the InfraLOB.

The paper's InfraD and InfraNUC are taken with the traffic removed, so they cannot
show the occlusion traffic causes: a low pole behind a parked truck still scores well.
Here each candidate is scanned over frames of the animated traffic, and for every
vehicle-frame (a vehicle whose box centre is inside the region in that frame) the
points on that vehicle are counted. Counts are additive over sensors (a set's points
on a vehicle are the union of its members' points), so a set's scores follow from
sums of the candidates' count vectors:

- ``share_N``: the share of vehicle-frames with at least N points (N = 5, 20, 50:
  what detectors need);
- ``mean_points``: points per vehicle-frame;
- ``never_seen``: the share of vehicles (over all frames) no point ever fell on.
"""

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import SettingsError

THRESHOLDS = (5, 20, 50)
RANK_BY = 20  # the threshold sets are ranked by


@dataclass
class Visibility:
    members: tuple
    shares: dict        # threshold -> share of vehicle-frames with >= threshold points
    mean_points: float
    never_seen: float

    @property
    def score(self):
        return self.shares[RANK_BY]

    def to_dict(self):
        out = {f"share_{n}": round(v, 6) for n, v in self.shares.items()}
        out.update(mean_points=round(self.mean_points, 4), never_seen=round(self.never_seen, 6))
        return out


class VisibilityCounts:
    """Per candidate, the points on each vehicle-frame.

    counts   (C, J) int points of candidate c on vehicle-frame j
    objects  (J,) object key of each vehicle-frame (to tell vehicles never seen)
    groups   (C,) optional mount of each candidate (a set uses each at most once)"""

    def __init__(self, counts, objects, groups=None, thresholds=THRESHOLDS):
        self.counts = np.asarray(counts, np.int64).reshape(len(counts), -1)
        self.objects = np.asarray(objects, dtype=object)
        if self.counts.shape[1] != len(self.objects):
            raise SettingsError("visibility counts need one column per vehicle-frame")
        self.thresholds = tuple(int(t) for t in thresholds)
        self.groups = (np.arange(len(self.counts)) if groups is None
                       else np.unique(np.asarray(groups), return_inverse=True)[1])
        _, self._object_of = np.unique(self.objects.astype(str), return_inverse=True) \
            if len(self.objects) else (None, np.zeros(0, np.int64))

    def evaluate(self, sets):
        """A ``Visibility`` per member tuple."""
        out = []
        for members in sets:
            members = tuple(sorted(int(i) for i in members))
            pts = self.counts[list(members)].sum(axis=0) if members else \
                np.zeros(self.counts.shape[1], np.int64)
            out.append(self._of(members, pts))
        return out

    def _of(self, members, pts):
        j = len(pts)
        shares = {t: float(np.count_nonzero(pts >= t) / j) if j else float("nan")
                  for t in self.thresholds}
        if j:
            per_object = np.bincount(self._object_of, weights=pts)
            never = float(np.count_nonzero(per_object == 0) / len(per_object))
            mean = float(pts.mean())
        else:
            never = mean = float("nan")
        return Visibility(members, shares, mean, never)

    def best(self, k, exhaustive_limit=20000):
        """The k-set (each mount at most once) with the highest share of vehicle-frames
        seen by at least ``RANK_BY`` points (ties: more points): every set when there
        are few, else greedy additions then best single swaps."""
        c = len(self.counts)
        sets = [s for s in itertools.islice(self._valid_sets(k), exhaustive_limit + 1)]
        if len(sets) <= exhaustive_limit:
            if not sets:
                raise SettingsError(f"k = {k} needs {k} distinct mounts")
            return max(self.evaluate(sets), key=lambda v: (v.score, v.mean_points))
        members = []
        for _ in range(k):
            free = [i for i in range(c) if self._may_add(members, i)]
            members.append(max(free, key=lambda i: self._key(members + [i])))
        improved = True
        while improved:
            improved = False
            for pos in range(k):
                rest = members[:pos] + members[pos + 1:]
                for i in range(c):
                    if i in members or not self._may_add(rest, i):
                        continue
                    cand = rest + [i]
                    if self._key(cand) > self._key(members):
                        members, improved = cand, True
        return self.evaluate([members])[0]

    def _key(self, members):
        v = self.evaluate([members])[0]
        return (v.score, v.mean_points)

    def _may_add(self, members, i):
        return i not in members and self.groups[i] not in {self.groups[m] for m in members}

    def _valid_sets(self, k):
        for combo in itertools.combinations(range(len(self.counts)), k):
            g = self.groups[list(combo)]
            if len(np.unique(g)) == len(g):
                yield combo


def ranks(values, higher_is_better=True):
    """1-based rank of each value (1 = best); ties share the better rank; NaN last."""
    v = np.asarray(values, np.float64)
    key = np.where(np.isnan(v), -np.inf if higher_is_better else np.inf, v)
    key = -key if higher_is_better else key
    order = np.argsort(key, kind="stable")
    out = np.empty(len(v), np.int64)
    sorted_keys = key[order]
    r = 0
    for pos, idx in enumerate(order):
        if pos == 0 or sorted_keys[pos] != sorted_keys[pos - 1]:
            r = pos + 1
        out[idx] = r
    return out
