"""A placement study judged by detection (``rls study --evaluate FRAMES``): every
candidate, the sets the study reports and a sample of the other sets of each k scored by
the detector's AP in the InfraLOB (``detection.py``), beside InfraD, InfraNUC and
visibility; and how well each of those metrics predicts the AP across the placements,
pooled and within each k (a pooled correlation mixes "more sensors" with "better
placement": sets of two have both more points and more AP)."""

from dataclasses import dataclass, field

import numpy as np

from .detection import background_record, headline, placement_score, reference_points

MIN_VEHICLE_FRAMES = 200  # fewer counted vehicle-frames than this: a notice says so


@dataclass
class StudyEvaluation:
    """The study's placements judged by detection.

    candidates   per candidate: its headline AP (None: nothing counted) and record
    sets         {members tuple: (headline AP, record)} of the sets scored: each k's
                 Pareto front and best set, the best set by visibility, and up to
                 ``cfg.evaluate_sets`` more of each k drawn from the sets the search
                 looked at (seeded), so the correlation within k has more than a handful
    best         {k: members} of the best set by AP among those of k members
    correlation  {metric name: correlation.correlation record} of AP with InfraD,
                 InfraNUC and each visibility share, over every placement scored
    by_k         {k: {metric name: correlation record}}: the same within each k
    placements   the rows the correlations ran over: name, members, AP and metrics
    vehicle_frames  the counted vehicle-frames (vehicles in the region, with enough
                 points, over the frames): the same for every placement
    frames, min_points, detect_ms (the detector's foreground per frame and candidate)
    detector     its name; background: what it learned (``background_record``)
    notices      what a reader should know (too few vehicle-frames)"""

    frames: list
    min_points: int
    candidates: list
    sets: dict
    best: dict
    correlation: dict
    placements: list
    detect_ms: float
    detector: str = ""
    background: dict = None
    by_k: dict = field(default_factory=dict)
    vehicle_frames: int = 0
    notices: list = field(default_factory=list)

    @classmethod
    def of(cls, cfg, scanner, cands, evaluations, searches, visibility):
        truths, polygon = scanner.truths, scanner.polygon
        ref = reference_points(evaluations, truths)
        mp = int(cfg.evaluate_min_points)
        det = scanner.detector
        records = [placement_score(det, [e], truths, polygon, mp, ref) for e in evaluations]
        sets = {}
        for members in _sets_to_score(cfg, searches, visibility):
            if members not in sets:
                rec = placement_score(det, [evaluations[i] for i in members], truths,
                                      polygon, mp, ref)
                sets[members] = (headline(rec), rec)
        scored = {**{(i,): (headline(r), r) for i, r in enumerate(records)}, **sets}
        best = {}
        for k in sorted(searches):
            pool = {m: v for m, v in scored.items() if len(m) == k and v[0] is not None}
            if pool:
                best[k] = max(pool, key=lambda m: (pool[m][0], -sum(m)))
        rows = [dict(members=list(m), sensors=[cands[i].name for i in m], ap=ap,
                     **_metrics(m, cands, searches, visibility))
                for m, (ap, _) in sorted(scored.items())]
        pooled, by_k = correlations(rows)
        n = vehicle_frames(records)
        notices = []
        if n < MIN_VEHICLE_FRAMES:
            notices.append(f"the evaluated frames hold {n} counted vehicle-frames (fewer "
                           f"than {MIN_VEHICLE_FRAMES}): each AP rests on few vehicles and "
                           "the correlations on noisy APs; evaluate more frames or busier "
                           "traffic")
        ms = 1000.0 * float(np.mean([e.detect_s for e in evaluations])) if evaluations else 0.0
        return cls(sorted(truths), mp, [(headline(r), r) for r in records], sets, best,
                   pooled, rows, ms, getattr(det, "name", type(det).__name__),
                   background_record(cfg, scanner.frame), by_k, n, notices)

    def ap_of(self, members):
        """The headline AP of a scored placement (a candidate or a scored set)."""
        members = tuple(members)
        return self.candidates[members[0]][0] if len(members) == 1 else self.sets[members][0]

    def to_dict(self, names):
        def strip(rec):  # the study keeps the summary, not every match
            return {k: v for k, v in rec.items() if k not in ("matches", "frames")}
        return {
            "frames": self.frames, "min_points": self.min_points,
            "headline": "vehicle AP_R40 at BEV IoU 0.5 (fraction of 1)",
            "ground_truth": ("boxes of vehicles, pedestrians and cyclists centred in the "
                             f"region on which the candidates together put >= "
                             f"{self.min_points} returns; the same for every placement"),
            "vehicle_frames": self.vehicle_frames,
            "detector": f"{self.detector}, early fusion over a set",
            "background": self.background,
            "detect_ms_per_frame": round(self.detect_ms, 2),
            "candidates": [{"candidate": names[i], "ap": ap, "result": strip(rec)}
                           for i, (ap, rec) in enumerate(self.candidates)],
            "sets": [{"members": list(m), "sensors": [names[i] for i in m], "ap": ap,
                      "result": strip(rec)} for m, (ap, rec) in sorted(self.sets.items())],
            "best_by_ap": {str(k): {"members": list(m), "sensors": [names[i] for i in m],
                                    "ap": self.ap_of(m)}
                           for k, m in sorted(self.best.items())},
            "placements": self.placements,
            "correlation": self.correlation,
            "correlation_by_k": {str(k): v for k, v in sorted(self.by_k.items())},
            "notices": self.notices,
        }


def _sets_to_score(cfg, searches, visibility):
    """The sets of two or more scored by detection, in order: each k's Pareto front and
    best set, the best set by visibility, then up to ``cfg.evaluate_sets`` more of the
    sets the search looked at, drawn with a generator seeded by (scan seed, k)."""
    out = []
    for k, s in sorted(searches.items()):
        if k < 2:
            continue
        wanted = [p.members for p in s.front] + [s.best.members]
        if visibility is not None:
            wanted.append(visibility.best[k].members)
        wanted = list(dict.fromkeys(tuple(int(i) for i in m) for m in wanted))
        others = [tuple(int(i) for i in p.members) for p in s.evaluated]
        others = [m for m in dict.fromkeys(others) if m not in wanted]
        extra = int(getattr(cfg, "evaluate_sets", 0))
        if extra > 0 and others:
            rng = np.random.default_rng([int(cfg.scan_seed), k])
            pick = rng.choice(len(others), size=min(extra, len(others)), replace=False)
            wanted += [others[i] for i in sorted(pick)]
        out += wanted
    return out


def correlations(rows):
    """(pooled {metric: record}, {k: {metric: record}}) of AP with each metric of the
    placement ``rows``, over all of them and within each number of sensors."""
    from ..evaluate.correlation import correlation

    names = [n for n in rows[0] if n not in ("members", "sensors", "ap")] if rows else []

    def of(sub):
        aps = np.array([np.nan if r["ap"] is None else r["ap"] for r in sub], np.float64)
        return {n: correlation(np.array([np.nan if r.get(n) is None else r[n] for r in sub],
                                        np.float64), aps) for n in names}

    ks = sorted({len(r["members"]) for r in rows})
    return of(rows), {k: of([r for r in rows if len(r["members"]) == k]) for k in ks}


def vehicle_frames(records):
    """The counted vehicle-frames of the evaluation (the same ground truth for every
    placement: the first record's)."""
    for rec in records:
        try:
            return int(rec["classes"]["vehicle"]["all"]["bev"]["0.5"]["gt"])
        except KeyError:
            continue
    return 0


def _metrics(members, cands, searches, visibility):
    """InfraD, InfraNUC and the visibility shares of the placement ``members``."""
    if len(members) == 1:
        c = cands[members[0]]
        out = {"infra_d": c.infra_d, "infra_nuc": c.infra_nuc}
        vis = visibility.candidates[members[0]] if visibility is not None else None
    else:
        k = len(members)
        found = [p for p in searches[k].evaluated if tuple(p.members) == members]
        out = {"infra_d": found[0].infra_d if found else np.nan,
               "infra_nuc": found[0].infra_nuc if found else np.nan}
        vis = visibility.sets[k].get(members) if visibility is not None else None
    if vis is not None:
        out.update({f"share_{t}": v for t, v in vis.shares.items()})
    return {k: (None if v is None or not np.isfinite(v) else float(v)) for k, v in out.items()}
