"""InfraLOB metrics: density (InfraD) and uniformity (InfraNUC) of a point cloud.

Following the RLS paper: the InfraLOB is a region of interest on the ground,
given as a polygon in world xy. Points (world frame, several clouds merged)
inside the outline with a chosen label (default road and sidewalk) are kept.

* ``InfraD = N / S``: N kept points, S the region's area (points per m^2).
* ``InfraNUC``: D equal disks of radius r are placed at random in the
  region; with n_i the points in disk i (counted in xy) and p = disk area / S,
  ``x_i = n_i / (N p)`` (1 on average for a uniform cloud) and
  ``InfraNUC = sqrt(1/D * sum (x_i - mean x)^2)``, the standard deviation of
  x. The paper's printed formula lacks the square; the standard deviation is
  what its NUC source (PU-Net) defines and what PCSim's code computes.

Defaults: D = 6000 disks of radius 0.7 m (PCSim's values for a 20 m x 30 m
region), seed 0, density map cells of 1 m.

Disk placement: by default a disk lies wholly inside the region (centre
uniform over the points at least r from every edge), so a uniform cloud
scores near 0 and mean x near 1. ``disk_placement="centre"`` instead only keeps
the centre inside (the paper's wording); disks then overhang the edge, catch
fewer points, and even a perfectly uniform cloud scores > 0 (about 0.1-0.2
for a 20 m x 30 m region with r = 0.7 m).
"""

import dataclasses
import json
import math
import numbers

import numpy as np

from ..errors import RegionError
from ..labels import DEFAULT_LABELS, label_id
from .polygon import as_polygon, points_in_polygon, sample_in_polygon, shoelace_area

DEFAULT_LOB_LABELS = ("road", "sidewalk")
DEFAULT_DISKS = 6000
DEFAULT_RADIUS_M = 0.7
DEFAULT_CELL_M = 1.0
DEFAULT_SEED = 0
DISK_PLACEMENTS = ("inside", "centre")
_PAIR_CHUNK = 4_000_000  # candidate (disk, point) pairs tested at once


def resolve_labels(labels):
    """Label ids for names or ids (a comma-separated string is split)."""
    if labels is None:
        labels = DEFAULT_LOB_LABELS
    if isinstance(labels, str):
        labels = [s.strip() for s in labels.split(",") if s.strip()]
    ids = []
    for item in labels:
        if isinstance(item, str) and item.strip().isdigit():
            item = int(item)
        ids.append(label_id(int(item) if isinstance(item, (np.integer,)) else item))
    if not ids:
        raise RegionError("no labels chosen for the InfraLOB selection")
    return sorted(set(ids))


def select_xy(clouds, polygon, label_ids, region=None):
    """(N, 2) xy of the points of all ``clouds`` inside ``polygon`` with a label in ``label_ids``.

    ``clouds``: one structured array or a list of them (fields x, y, label),
    already in world coordinates. Returns also the count of points inside the
    outline regardless of label, for error messages. ``region``: a
    ``PreparedPolygon`` of ``polygon``, for many clouds in the same outline.

    Only the points in the outline's bounding box go through the outline test (the
    test ``points_in_polygon`` starts with), and only their labels are looked at: the
    same points in the same order as testing every point, for a fraction of the work.
    """
    if isinstance(clouds, np.ndarray):
        clouds = [clouds]
    parts, inside_any = [], 0
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    for pts in clouds:
        if len(pts) == 0:
            continue
        # contiguous copies: a study's records are packed, and numpy is slow on their
        # unaligned fields
        x, y = np.array(pts["x"], np.float64), np.array(pts["y"], np.float64)
        box = x >= lo[0]
        box &= x <= hi[0]
        box &= y >= lo[1]
        box &= y <= hi[1]
        idx = np.flatnonzero(box)
        xy = np.empty((len(idx), 2))
        xy[:, 0], xy[:, 1] = x.take(idx), y.take(idx)
        inside = points_in_polygon(xy, polygon) if region is None else region.contains(xy)
        inside_any += int(np.count_nonzero(inside))
        inside &= label_mask(pts["label"].take(idx), label_ids)
        parts.append(np.compress(inside, xy, axis=0))
    if len(parts) == 1:
        return parts[0], inside_any
    xy = np.concatenate(parts) if parts else np.empty((0, 2))
    return xy, inside_any


def label_mask(labels, label_ids):
    """``np.isin(labels, label_ids)``; by a look-up table for the usual small ids."""
    wanted = np.asarray(label_ids, dtype=np.int64)
    labels = np.asarray(labels)
    if labels.dtype.kind != "u" or len(wanted) == 0 or wanted.min() < 0 \
            or wanted.max() >= 65536:
        return np.isin(labels, wanted)
    table = np.zeros(int(wanted.max()) + 2, bool)  # the last entry stays False:
    table[wanted] = True                            # larger labels are clipped onto it
    return table.take(labels, mode="clip")


def count_in_disks(xy, centres, radius, cells_per_radius=4):
    """Points of ``xy`` within ``radius`` (inclusive) of each centre, in xy.

    Grid hashing: points are sorted by cell (size radius / cells_per_radius,
    row-major keys), so the cells a disk's chord crosses in one grid row are
    one contiguous slice of the sorted points. Only those candidates (about
    1.4x the disk area) are tested exactly. Disks are processed in chunks so
    memory stays bounded. Exact integer counts, independent of point order.
    """
    xy = np.asarray(xy, dtype=np.float64)
    centres = np.asarray(centres, dtype=np.float64)
    counts = np.zeros(len(centres), dtype=np.int64)
    if len(xy) == 0 or len(centres) == 0:
        return counts
    r = float(radius)
    k = int(cells_per_radius)
    h = r / k
    lo = np.minimum(xy.min(axis=0), centres.min(axis=0)) - 2 * r
    cell = np.floor((xy - lo) / h).astype(np.int64)
    cc = np.floor((centres - lo) / h).astype(np.int64)
    nx = int(max(cell[:, 0].max(), cc[:, 0].max())) + 2 * k + 3  # chords never wrap a row
    key = cell[:, 1] * nx + cell[:, 0]
    order = np.argsort(key, kind="stable")
    key = key[order]
    px, py = xy[order, 0], xy[order, 1]
    cx, cy = centres[:, 0], centres[:, 1]
    slack = 1e-9 * max(1.0, r, float(np.abs(lo).max()))  # keep rounding-edge points as candidates
    starts, stops = [], []
    for dy in range(-k - 1, k + 2):
        row = cc[:, 1] + dy
        band_lo = lo[1] + row * h
        dmin = np.maximum(0.0, np.maximum(band_lo - cy, cy - (band_lo + h)))
        half = np.sqrt(np.maximum(r * r - dmin * dmin, 0.0)) + slack
        c0 = np.floor((cx - half - lo[0]) / h).astype(np.int64)
        c1 = np.floor((cx + half - lo[0]) / h).astype(np.int64)
        start = np.searchsorted(key, row * nx + c0, side="left")
        stop = np.searchsorted(key, row * nx + c1, side="right")
        stop[dmin > r + slack] = start[dmin > r + slack]
        starts.append(start)
        stops.append(stop)
    nrow = len(starts)
    start = np.stack(starts, axis=1).ravel()  # (D * nrow,), disk-major
    stop = np.stack(stops, axis=1).ravel()
    owner = np.repeat(np.arange(len(centres)), nrow)
    length = stop - start
    ends = np.cumsum(length)
    total = int(ends[-1])
    # split the (disk, row) slices into chunks of about _PAIR_CHUNK candidates
    bounds = np.searchsorted(ends, np.arange(_PAIR_CHUNK, total, _PAIR_CHUNK))
    edges = np.unique(np.concatenate([[0], bounds + 1, [len(length)]]))
    r2 = r * r
    for a, b in zip(edges[:-1], edges[1:]):
        ln = length[a:b]
        n = int(ln.sum())
        if n == 0:
            continue
        first = np.cumsum(ln) - ln
        idx = np.arange(n, dtype=np.int64) + np.repeat(start[a:b] - first, ln)
        who = np.repeat(owner[a:b], ln)
        ddx = px[idx] - cx[who]
        ddy = py[idx] - cy[who]
        hit = ddx * ddx + ddy * ddy <= r2
        counts += np.bincount(who[hit], minlength=len(centres))
    return counts


def infra_d(n_points, area_m2):
    """Points per square metre."""
    return n_points / area_m2


def infra_nuc_rows(disk_counts, n_points, p):
    """The InfraNUC formula, once for every caller: per row, the standard deviation of
    ``n_i / (N p)`` over the disks.

    disk_counts  (..., D) points in each disk
    n_points     (...)    points N of the cloud (or set of clouds) each row counts
    p            the share of the region one disk covers
    Returns (...) float64, NaN for a row with no points or no point in any disk (no
    estimate, not 'perfectly uniform')."""
    n = np.asarray(n_points, dtype=np.float64)
    c = np.asarray(disk_counts, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        x = c / (n[..., None] * p)
        nuc = np.sqrt(np.mean((x - x.mean(axis=-1, keepdims=True)) ** 2, axis=-1))
    return np.where((n == 0) | (c.sum(axis=-1) == 0), np.nan, nuc)


def infra_nuc(disk_counts, n_points, p):
    """InfraNUC of one cloud: ``infra_nuc_rows`` of its disk counts.

    Raises RegionError when no disk holds a point: the spread of all-zero counts is 0,
    which would read as perfectly uniform when it is no estimate at all."""
    counts = np.asarray(disk_counts, dtype=np.float64)
    if counts.sum() == 0:
        raise RegionError(
            f"none of the {len(counts)} disks holds any of the {n_points} points, so InfraNUC "
            "cannot be estimated: use larger or more disks (--radius, --disks)")
    return float(infra_nuc_rows(counts[None, :], [n_points], p)[0])


@dataclasses.dataclass
class DensityMap:
    """Points per m^2 on a grid over the region's bounding box; NaN outside the outline.

    ``values[i, j]`` covers x in [x0 + j c, x0 + (j+1) c), y in [y0 + i c, ...):
    row 0 is the southern (lowest y) row. A cell counts as outside when its
    centre is outside the outline; boundary cells are partly empty.
    """

    origin_xy: tuple
    cell_m: float
    values: np.ndarray

    def to_dict(self):
        rows = [[None if not math.isfinite(v) else round(float(v), 6) for v in row] for row in self.values]
        return {
            "origin_xy": [float(self.origin_xy[0]), float(self.origin_xy[1])],
            "cell_m": float(self.cell_m),
            "shape": list(self.values.shape),
            "row_order": "south_to_north (row 0 at the lowest y)",
            "units": "points per square metre",
            "values": rows,
        }

    def to_png(self, pixels_per_cell=None):
        """PNG bytes, north up, viridis from 0 to the maximum; outside cells transparent."""
        from ..output.png import colormap, encode_png

        img = colormap(self.values[::-1], vmin=0.0)
        if pixels_per_cell is None:
            pixels_per_cell = max(1, 512 // max(img.shape[:2]))
        k = int(pixels_per_cell)
        img = np.repeat(np.repeat(img, k, axis=0), k, axis=1)
        return encode_png(img)


def density_map(xy, polygon, cell_m=DEFAULT_CELL_M):
    """A ``DensityMap`` of the (N, 2) points over ``polygon``'s bounding box."""
    if not (cell_m > 0 and math.isfinite(cell_m)):
        raise RegionError(f"density cell size must be a positive number of metres, got {cell_m}")
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    nx = max(1, int(math.ceil((hi[0] - lo[0]) / cell_m - 1e-9)))
    ny = max(1, int(math.ceil((hi[1] - lo[1]) / cell_m - 1e-9)))
    if nx * ny > 25_000_000:
        raise RegionError(f"density map of {nx} x {ny} cells is too large; choose a larger cell size")
    ij = np.floor((np.asarray(xy) - lo) / cell_m).astype(np.int64)
    ij[:, 0] = np.clip(ij[:, 0], 0, nx - 1)
    ij[:, 1] = np.clip(ij[:, 1], 0, ny - 1)
    counts = np.bincount(ij[:, 1] * nx + ij[:, 0], minlength=nx * ny).reshape(ny, nx)
    values = counts / (cell_m * cell_m)
    gx, gy = np.meshgrid(lo[0] + (np.arange(nx) + 0.5) * cell_m, lo[1] + (np.arange(ny) + 0.5) * cell_m)
    outside = ~points_in_polygon(np.stack([gx.ravel(), gy.ravel()], axis=1), polygon).reshape(ny, nx)
    values[outside] = np.nan
    return DensityMap((float(lo[0]), float(lo[1])), float(cell_m), values)


@dataclasses.dataclass
class InfraLOBResult:
    infra_d: float
    infra_nuc: float
    n_points: int
    area_m2: float
    disks: int
    radius_m: float
    seed: int
    labels: list
    disk_placement: str
    mean_disk_count: float
    polygon_xy: list
    density: DensityMap = None

    def to_dict(self):
        out = dataclasses.asdict(self)
        out["density"] = self.density.to_dict() if self.density is not None else None
        return out

    def to_json(self, indent=2):
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)


def disk_rng(seed):
    """The generator that places the disks: ``numpy.random.default_rng(seed)`` of a
    whole number ``seed`` >= 0 (all of it); ``RegionError`` for anything else."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise RegionError(f"the disk seed must be a whole number >= 0, got {seed!r}")
    return np.random.default_rng(int(seed))


def infra_lob_metrics(
    clouds,
    polygon,
    *,
    labels=None,
    disks=DEFAULT_DISKS,
    radius=DEFAULT_RADIUS_M,
    seed=DEFAULT_SEED,
    cell=DEFAULT_CELL_M,
    disk_placement="inside",
    with_density=True,
):
    """InfraD and InfraNUC of ``clouds`` (world frame) in the region ``polygon``.

    Raises ``RegionError`` for a degenerate outline, bad parameters, or a
    region that holds no selected points.
    """
    poly = as_polygon(polygon)
    area = abs(shoelace_area(poly))
    disks = int(disks)
    if disks < 1:
        raise RegionError(f"need at least one disk, got {disks}")
    if not (radius > 0 and math.isfinite(radius)):
        raise RegionError(f"disk radius must be a positive number of metres, got {radius}")
    if disk_placement not in DISK_PLACEMENTS:
        raise RegionError(f"disk placement must be one of {', '.join(DISK_PLACEMENTS)}")
    ids = resolve_labels(labels)
    names = [DEFAULT_LABELS[i] for i in ids]
    xy, inside_any = select_xy(clouds, poly, ids)
    n = len(xy)
    if n == 0:
        raise RegionError(
            f"the region ({area:.1f} m^2) holds no points labelled {', '.join(names)} "
            f"({inside_any} points of other labels inside it); check the outline, the labels, "
            "and that the clouds are in world coordinates"
        )
    p = math.pi * radius * radius / area
    rng = disk_rng(seed)
    margin = radius if disk_placement == "inside" else 0.0
    centres = sample_in_polygon(poly, disks, rng, margin=margin)
    counts = count_in_disks(xy, centres, radius)
    return InfraLOBResult(
        infra_d=infra_d(n, area),
        infra_nuc=infra_nuc(counts, n, p),
        n_points=n,
        area_m2=area,
        disks=disks,
        radius_m=float(radius),
        seed=int(seed),
        labels=names,
        disk_placement=disk_placement,
        mean_disk_count=float(counts.mean()),
        polygon_xy=poly.tolist(),
        density=density_map(xy, poly, cell) if with_density else None,
    )
