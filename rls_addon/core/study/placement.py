"""Sets of sensors: combine per-candidate InfraLOB counts and search for the best sets.

Pure numpy. The study (``study.run_study``) scans each candidate placement once and hands over,
per candidate, the number of kept points in the InfraLOB and the point count of
each of the same seeded disks (``DiskLayout``). Counts are additive over merged
clouds, so the metrics of any set of candidates follow from sums of these vectors
without touching the points again:

    N(S) = sum_c n_c,  counts(S) = sum_c counts_c,
    InfraD(S) = N(S) / area,  InfraNUC(S) = std(counts(S) / (N(S) p)).

The search looks for sets of k candidates with high InfraD and low InfraNUC. The
two goals conflict, so the answer is a Pareto front (no member is beaten on both).
When the number of k-sets is small (``exhaustive_limit``) every set is evaluated
and the front is exact; otherwise greedy construction followed by a best-swap
refinement is run for a range of weights between the two goals
(``score = w D/D_ref - (1 - w) NUC/NUC_ref``) and the sets found are filtered to
their front. ``best`` is the front member with the highest balanced score (w = 0.5).
"""

import dataclasses
import itertools
import math

import numpy as np

from ..metrics.disk_counter import DiskCounter
from ..errors import InputError, RegionError, SettingsError
from ..metrics.infra import (DEFAULT_DISKS, DEFAULT_RADIUS_M, DEFAULT_SEED, disk_rng,
                             infra_nuc_rows, select_xy)
from ..metrics.polygon import PreparedPolygon, as_polygon, sample_in_polygon, shoelace_area

DEFAULT_WEIGHTS = tuple(np.round(np.linspace(0.0, 1.0, 11), 2))
DEFAULT_EXHAUSTIVE_LIMIT = 20000
EVALUATE_CHUNK = 64  # sets summed and scored at a time (CandidateCounts.evaluate)


@dataclasses.dataclass
class DiskLayout:
    """The seeded disks of an InfraLOB, placed exactly as ``infra_lob_metrics`` places
    them (same seed, radius, placement), so single-candidate values match it."""

    polygon: np.ndarray
    area_m2: float
    centres: np.ndarray
    radius_m: float
    seed: int
    disk_placement: str = "inside"
    _counter: object = dataclasses.field(default=None, init=False, repr=False, compare=False)
    _region: object = dataclasses.field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def make(cls, polygon, disks=DEFAULT_DISKS, radius=DEFAULT_RADIUS_M, seed=DEFAULT_SEED,
             disk_placement="inside"):
        poly = as_polygon(polygon)
        if int(disks) < 1:
            raise RegionError(f"need at least one disk, got {disks}")
        if not (radius > 0 and math.isfinite(radius)):
            raise RegionError(f"disk radius must be a positive number of metres, got {radius}")
        rng = disk_rng(seed)
        margin = radius if disk_placement == "inside" else 0.0
        centres = sample_in_polygon(poly, int(disks), rng, margin=margin)
        return cls(poly, abs(shoelace_area(poly)), centres, float(radius), int(seed), disk_placement)

    @property
    def p(self):
        """Disk area over region area."""
        return math.pi * self.radius_m ** 2 / self.area_m2

    def prepare(self):
        """Work out what depends on the layout alone (the disks' ``DiskCounter``, the
        outline's ``PreparedPolygon``); else done on first use. A study's scanner calls
        this while it prepares the scene, so its first candidate does not pay for it."""
        self.counter()
        self.region()

    def region(self):
        """The outline's ``PreparedPolygon``, made on first use."""
        if self._region is None:
            self._region = PreparedPolygon(self.polygon)
        return self._region

    def select(self, clouds, label_ids):
        """(N, 2) xy of the kept points (inside the outline, wanted labels): ``select_xy``'s,
        with the outline's grid of decided cells worked out once per layout."""
        return select_xy(clouds, self.polygon, label_ids, self.region())[0]

    def counter(self):
        """The layout's ``DiskCounter`` (what depends on the disks alone), made on first
        use."""
        if self._counter is None:
            self._counter = DiskCounter(self.centres, self.radius_m)
        return self._counter

    def counts(self, xy):
        """Points of ``xy`` in each disk: ``count_in_disks``'s counts, with what depends on
        the disks alone worked out once per layout (``DiskCounter``)."""
        return self.counter().counts(xy)


def set_metrics(n_points, disk_counts, area_m2, p):
    """InfraD and InfraNUC of sets given their summed counts.

    n_points     (S,) kept points per set
    disk_counts  (S, D) summed disk counts per set
    Returns (infra_d (S,), infra_nuc (S,)); InfraNUC is NaN for a set with no points or
    with no point in any disk (no estimate, not 'perfectly uniform').
    """
    d = np.asarray(n_points, dtype=np.float64) / area_m2
    return d, infra_nuc_rows(disk_counts, n_points, p)


def pareto_front(infra_d, infra_nuc):
    """Indices of the non-dominated points (InfraD high, InfraNUC low), sorted by
    InfraD descending. A point dominates another when it is at least as good on
    both and better on one; exact duplicates are all kept. NaN InfraNUC counts as
    the worst uniformity."""
    d = np.asarray(infra_d, dtype=np.float64)
    u = np.asarray(infra_nuc, dtype=np.float64)
    u = np.where(np.isnan(u), np.inf, u)
    order = np.lexsort((u, -d))  # by D desc, then NUC asc
    front, best_u, last = [], None, None
    for i in order:
        if best_u is None or u[i] < best_u:
            front.append(i)
            best_u = u[i]
            last = (d[i], u[i])
        elif last is not None and (d[i], u[i]) == last:
            front.append(i)  # an exact tie with the last front point
    return np.array(front, dtype=np.int64)


@dataclasses.dataclass
class Placement:
    members: tuple  # candidate indices, sorted
    infra_d: float
    infra_nuc: float
    n_points: int

    def to_dict(self, names=None):
        out = {"members": list(self.members), "infra_d": self.infra_d,
               "infra_nuc": None if not math.isfinite(self.infra_nuc) else self.infra_nuc,
               "n_points": self.n_points}
        if names is not None:
            out["sensors"] = [names[i] for i in self.members]
        return out


@dataclasses.dataclass
class SearchResult:
    k: int
    method: str            # "exhaustive" or "greedy+swap"
    evaluated: list        # Placement, every distinct set looked at (bounded)
    front: list            # Placement on the Pareto front, InfraD descending
    best: Placement        # front member with the best balanced score
    sets_total: int        # number of valid k-sets


class CandidateCounts:
    """Per-candidate kept-point totals and disk counts, for fast set evaluation.

    n       (C,) kept points in the InfraLOB per candidate
    counts  (C, D) points per disk per candidate
    groups  (C,) optional group id per candidate (its mount): a set uses each
            group at most once (one LiDAR per mount position)
    """

    def __init__(self, n, counts, area_m2, p, groups=None):
        self.n = np.asarray(n, dtype=np.int64)
        self.counts = np.asarray(counts, dtype=np.int64)
        if self.counts.ndim != 2 or len(self.counts) != len(self.n):
            raise InputError("counts must be (candidates, disks) matching n")
        self.area_m2 = float(area_m2)
        self.p = float(p)
        self.groups = (np.arange(len(self.n)) if groups is None
                       else np.unique(np.asarray(groups), return_inverse=True)[1])
        self._single = None  # see _refs

    def __len__(self):
        return len(self.n)

    def evaluate(self, sets):
        """Placements for an iterable of member tuples."""
        sets = [tuple(sorted(int(i) for i in s)) for s in sets]
        if not sets:
            return []
        idx = np.array(sets, dtype=np.int64)
        n = self.n[idx].sum(axis=1)
        d, u = np.empty(len(idx)), np.empty(len(idx))
        # A few hundred sets at a time: a whole batch's (sets, disks) temporaries ran to
        # hundreds of MB, each page of them a fault on first touch (2.2 s for the 6,300
        # pairs of 120 candidates over 6,000 disks, 0.2-0.3 s in chunks; the same numbers,
        # row by row)
        for lo in range(0, len(idx), EVALUATE_CHUNK):
            part = idx[lo:lo + EVALUATE_CHUNK]
            c = self.counts[part[:, 0]]
            for j in range(1, part.shape[1]):
                c += self.counts[part[:, j]]
            hi = lo + len(part)
            d[lo:hi], u[lo:hi] = set_metrics(n[lo:hi], c, self.area_m2, self.p)
        return [Placement(s, float(a), float(b), int(m)) for s, a, b, m in zip(sets, d, u, n)]

    def valid(self, members):
        g = self.groups[list(members)]
        return len(np.unique(g)) == len(g)

    def count_sets(self, k):
        """Number of k-sets that use each group at most once."""
        sizes = np.bincount(self.groups)
        # elementary symmetric polynomial e_k of the group sizes
        e = np.zeros(k + 1)
        e[0] = 1.0
        for s in sizes:
            e[1:] = e[1:] + s * e[:-1]
        return int(round(e[k]))

    def all_sets(self, k):
        for combo in itertools.combinations(range(len(self)), k):
            if self.valid(combo):
                yield combo

    # -- scalarised search -------------------------------------------------------
    def _refs(self, k):
        """(InfraD reference, InfraNUC reference) of k-sets: k times the best single
        candidate's density and the worst single uniformity."""
        if self._single is None:  # the candidates alone, once (scores ask per set)
            d1, u1 = set_metrics(self.n, self.counts, self.area_m2, self.p)
            finite = u1[np.isfinite(u1)]
            self._single = (float(np.max(d1)),
                            max(float(finite.max()) if len(finite) else 1.0, 1e-12))
        d_max, u_ref = self._single
        return max(d_max * k, 1e-12), u_ref

    def _scores(self, n, c, w, d_ref, u_ref):
        d, u = set_metrics(n, c, self.area_m2, self.p)
        u = np.where(np.isfinite(u), u, 10.0 * u_ref)
        return w * d / d_ref - (1.0 - w) * u / u_ref

    def greedy_swap(self, k, weight, max_rounds=100):
        """One local optimum of ``weight * D/D_ref - (1 - weight) * NUC/NUC_ref`` over
        k-sets: greedy additions, then best-improvement single swaps until none helps."""
        if k > len(np.unique(self.groups)):
            raise SettingsError(f"k = {k} exceeds the number of distinct mounts")
        d_ref, u_ref = self._refs(k)
        members = []
        n_tot, c_tot = 0, np.zeros(self.counts.shape[1], dtype=np.int64)
        for _ in range(k):
            free = np.array([i for i in range(len(self)) if self._may_add(members, i)])
            s = self._scores(n_tot + self.n[free], c_tot + self.counts[free], weight, d_ref, u_ref)
            j = int(free[np.argmax(s)])
            members.append(j)
            n_tot += self.n[j]
            c_tot = c_tot + self.counts[j]
        current = float(self._scores(np.array([n_tot]), c_tot[None], weight, d_ref, u_ref)[0])
        for _ in range(max_rounds):
            best = (current + 1e-12, None, None)
            for pos, out in enumerate(members):
                rest = members[:pos] + members[pos + 1:]
                free = np.array([i for i in range(len(self))
                                 if i not in members and self._may_add(rest, i)], dtype=np.int64)
                if len(free) == 0:
                    continue
                n_b = n_tot - self.n[out]
                c_b = c_tot - self.counts[out]
                s = self._scores(n_b + self.n[free], c_b + self.counts[free], weight, d_ref, u_ref)
                j = int(np.argmax(s))
                if s[j] > best[0]:
                    best = (float(s[j]), pos, int(free[j]))
            if best[1] is None:
                break
            current, pos, new = best
            out = members[pos]
            members[pos] = new
            n_tot += self.n[new] - self.n[out]
            c_tot = c_tot + self.counts[new] - self.counts[out]
        return tuple(sorted(members))

    def _may_add(self, members, i):
        return i not in members and self.groups[i] not in set(self.groups[members].tolist())

    def search(self, k, weights=DEFAULT_WEIGHTS, exhaustive_limit=DEFAULT_EXHAUSTIVE_LIMIT):
        """Pareto front of k-sets (see the module doc). Raises SettingsError when
        there are not k distinct mounts."""
        k = int(k)
        if k < 1:
            raise SettingsError("k must be at least 1")
        total = self.count_sets(k)
        if total == 0:
            raise SettingsError(f"k = {k} needs {k} distinct mounts; the candidates have "
                             f"{len(np.unique(self.groups))}")
        if total <= exhaustive_limit:
            method = "exhaustive"
            evaluated = []
            batch = []
            for combo in self.all_sets(k):
                batch.append(combo)
                if len(batch) >= 4096:
                    evaluated += self.evaluate(batch)
                    batch = []
            evaluated += self.evaluate(batch)
        else:
            method = "greedy+swap"
            found = {self.greedy_swap(k, w) for w in weights}
            evaluated = self.evaluate(sorted(found))
        d = np.array([p.infra_d for p in evaluated])
        u = np.array([p.infra_nuc for p in evaluated])
        front = [evaluated[i] for i in pareto_front(d, u)]
        best = max(front, key=lambda p: self.balanced(p, k))
        return SearchResult(k, method, evaluated, front, best, total)

    def balanced(self, placement, k):
        d_ref, u_ref = self._refs(k)
        u = placement.infra_nuc if math.isfinite(placement.infra_nuc) else 10.0 * u_ref
        return 0.5 * placement.infra_d / d_ref - 0.5 * u / u_ref
