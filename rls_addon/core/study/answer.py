"""A study's answer as the Study panel shows it in the scene: each candidate's scores
(what its marker is coloured by), a short table (every candidate, and for each larger
k its Pareto front and best set; every set is in ``placements.csv``), the best set of
each k as poses for LiDAR objects, and colours for a score (the best yellow, the worst
dark purple, no value grey). The numbers are the report's (``report.candidate_rows``,
``report.placement_rows``): what ``rls study`` writes."""

import dataclasses
import math

import numpy as np

from ..choices import STUDY_SCORES
from ..output.png import colormap
from ..metrics.visibility import RANK_BY
from .report import AP_FIELD, candidate_rows, placement_rows

# Where each score is in the report's rows, and whether lower is better
SCORE_FIELDS = {"infra_d": "infra_d", "infra_nuc": "infra_nuc",
                "visibility": f"share_{RANK_BY}", "ap": AP_FIELD}
LOWER_IS_BETTER = {"infra_nuc"}
NO_VALUE_RGBA = (0.5, 0.5, 0.5, 1.0)


def _number(value):
    return float(value) if value is not None and math.isfinite(float(value)) else math.nan


def available_scores(result):
    """The score ids this study has values for (visibility with traffic frames, AP
    with evaluation frames)."""
    out = ["infra_d", "infra_nuc"]
    if result.visibility is not None:
        out.append("visibility")
    if result.evaluation is not None:
        out.append("ap")
    return out


def candidate_scores(result):
    """{score id: (candidates,) float64, NaN where a candidate has none} for every
    score of ``available_scores``."""
    rows = candidate_rows(result)
    return {s: np.array([_number(r.get(SCORE_FIELDS[s])) for r in rows])
            for s in available_scores(result)}


@dataclasses.dataclass
class TableRow:
    k: int
    sensors: str
    members: tuple
    points: int
    infra_d: float
    infra_nuc: float
    visibility: float   # NaN without traffic frames
    ap: float           # NaN without evaluation frames (or for a set not scored)
    pareto: bool
    best: bool


def table_rows(result):
    """The rows of the panel's table: every candidate (k = 1: all its sets) and, for
    each larger k, the sets on its Pareto front and its best set, in the report's
    order (per k by InfraD, densest first)."""
    out = []
    for r in placement_rows(result):
        if r["k"] != 1 and not (r["pareto"] or r["best"]):
            continue
        out.append(TableRow(
            int(r["k"]), r["sensors"], tuple(int(i) for i in r["members"].split()),
            int(r["points_in_lob"]), _number(r["infra_d"]), _number(r["infra_nuc"]),
            _number(r.get(SCORE_FIELDS["visibility"])), _number(r.get(AP_FIELD)),
            bool(r["pareto"]), bool(r["best"])))
    return out


def best_sets(result):
    """{k: [Candidate, ...]} the best set of each k (its members' poses and names)."""
    return {k: [result.candidates[i] for i in s.best.members]
            for k, s in sorted(result.searches.items())}


def score_colours(values, score):
    """(n, 4) RGBA in 0..1 for ``values`` of ``score`` (a ``STUDY_SCORES`` id): viridis
    from the worst value (dark purple) to the best (yellow), NaN grey."""
    STUDY_SCORES.check(score)
    v = np.asarray(values, dtype=np.float64)
    if score in LOWER_IS_BETTER:
        v = -v
    rgba = colormap(v).astype(np.float64) / 255.0
    rgba[~np.isfinite(v)] = NO_VALUE_RGBA
    return rgba


MARKER_BANDS = 16  # Solid shading shows a material's colour: the markers' in bands


def score_bands(values, score, n=MARKER_BANDS):
    """(n_values,) int: each value's band for Solid shading, which cannot show an
    object's own colour but its material's: 0 for no value, then 1..``n`` from the
    worst value to the best in ``n`` equal steps (the best in band ``n``; all in band
    ``n`` when every value is the same, as ``score_colours`` colours them alike)."""
    STUDY_SCORES.check(score)
    v = np.asarray(values, dtype=np.float64)
    if score in LOWER_IS_BETTER:
        v = -v
    finite = np.isfinite(v)
    band = np.zeros(v.shape, np.int32)
    if finite.any():
        lo, hi = float(v[finite].min()), float(v[finite].max())
        t = (v[finite] - lo) / (hi - lo) if hi > lo else np.ones(int(finite.sum()))
        band[finite] = 1 + np.minimum(np.floor(t * n), n - 1).astype(np.int32)
    return band


def band_colours(n=MARKER_BANDS):
    """(n + 1, 4) RGBA in 0..1 (sRGB) of ``score_bands``' bands: no value grey, then
    the markers' viridis at each band's middle."""
    out = np.empty((n + 1, 4))
    out[0] = NO_VALUE_RGBA
    out[1:] = colormap((np.arange(n) + 0.5) / n, vmin=0.0, vmax=1.0).astype(np.float64) / 255.0
    return out


def score_range_text(values, score):
    """'InfraD 6.2 (dark) to 19.2 (yellow)': what the markers' colours span."""
    v = np.asarray(values, dtype=np.float64)
    finite = v[np.isfinite(v)]
    label = STUDY_SCORES.label(score)
    if not finite.size:
        return f"{label}: no values"
    worst, best = ((finite.max(), finite.min()) if score in LOWER_IS_BETTER
                   else (finite.min(), finite.max()))
    return f"{label} {worst:.3g} (dark) to {best:.3g} (yellow)"


# The table's columns it may be sorted by, and whether the best comes first when the
# column is sorted (descending for "higher is better")
TABLE_SORTS = {"k": False, "sensors": False, "infra_d": True, "infra_nuc": False,
               "visibility": True, "ap": True}


def table_order(rows, by):
    """Indices of ``rows`` (objects with ``TableRow``'s attributes) sorted by the column
    ``by``: scores best first, rows without a value (NaN) last, ties by k then
    InfraD."""
    if by not in TABLE_SORTS:
        raise KeyError(f"unknown column {by!r}; choose one of {', '.join(TABLE_SORTS)}")
    descending = TABLE_SORTS[by]

    def key(i):
        r = rows[i]
        v = getattr(r, by)
        if isinstance(v, str):
            return (0, v, r.k, -r.infra_d)
        v = float(v)
        if not math.isfinite(v):
            return (1, 0.0, r.k, -r.infra_d)
        return (0, -v if descending else v, r.k, -r.infra_d)

    return sorted(range(len(rows)), key=key)
