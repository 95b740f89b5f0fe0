"""InfraLOB metrics: exactness, stability and the failure modes."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.errors import RegionError, RLSError
from rls_addon.core.metrics.infra import (
    count_in_disks,
    density_map,
    infra_lob_metrics,
    infra_nuc,
    label_mask,
    resolve_labels,
    select_xy,
)
from rls_addon.core.output.png import decode_png_rgba
from rls_addon.core.points import empty_points
from rls_addon.core.metrics.polygon import (
    PreparedPolygon,
    as_polygon,
    points_in_polygon,
    polygon_area,
    sample_in_polygon,
)

RECT = [[0.0, 0.0], [20.0, 0.0], [20.0, 30.0], [0.0, 30.0]]
ROAD, SIDEWALK, BUILDING = 1, 2, 3


def cloud(x, y, label=ROAD):
    p = empty_points(len(x))
    p["x"], p["y"] = x, y
    p["label"] = label
    return p


def grid_cloud(spacing=0.1, w=20.0, h=30.0):
    xs = np.arange(spacing / 2, w, spacing)
    ys = np.arange(spacing / 2, h, spacing)
    gx, gy = np.meshgrid(xs, ys)
    return cloud(gx.ravel(), gy.ravel())


def test_infra_d_exact_on_known_grid():
    pts = grid_cloud(0.5)  # 40 x 60 points in 600 m^2
    r = infra_lob_metrics(pts, RECT, disks=100)
    assert r.n_points == 2400
    assert r.area_m2 == 600.0
    assert r.infra_d == 4.0


def test_regular_grid_is_nearly_uniform_and_clusters_are_not():
    grid = infra_lob_metrics(grid_cloud(0.1), RECT)
    assert grid.infra_nuc < 0.03  # lattice counting noise only
    assert abs(grid.mean_disk_count / (grid.n_points * math.pi * 0.49 / 600) - 1) < 0.01
    rng = np.random.default_rng(3)
    centres = rng.uniform([2, 2], [18, 28], size=(30, 2))
    pts = centres[rng.integers(0, 30, 60000)] + rng.normal(0, 0.8, (60000, 2))
    pts = pts[points_in_polygon(pts, as_polygon(RECT))]
    clustered = infra_lob_metrics(cloud(pts[:, 0], pts[:, 1]), RECT)
    assert clustered.infra_nuc > 1.0
    assert clustered.infra_nuc > 30 * grid.infra_nuc


def test_uniform_random_cloud_matches_poisson_expectation():
    rng = np.random.default_rng(1)
    n = 200_000
    r = infra_lob_metrics(cloud(rng.uniform(0, 20, n), rng.uniform(0, 30, n)), RECT)
    expected = 1 / math.sqrt(n * math.pi * 0.49 / 600)  # Poisson: sd / mean = 1/sqrt(mean)
    assert r.infra_nuc == pytest.approx(expected, rel=0.1)


def test_spread_over_seeds_shrinks_with_more_disks():
    rng = np.random.default_rng(7)
    n = 20000
    pts = cloud(rng.uniform(0, 20, n) ** 1.0, (rng.uniform(0, 1, n) ** 2) * 30)  # denser near y=0
    spread = {}
    for d in (100, 1000, 6000):
        vals = [infra_lob_metrics(pts, RECT, disks=d, seed=s, with_density=False).infra_nuc for s in range(12)]
        spread[d] = float(np.std(vals))
    print("InfraNUC spread over 12 seeds by disk count:", spread)
    assert spread[1000] < spread[100]
    assert spread[6000] < spread[1000]
    assert spread[6000] < 0.5 * spread[100]


def test_point_order_does_not_change_results():
    rng = np.random.default_rng(2)
    n = 30000
    pts = cloud(rng.uniform(-1, 21, n), rng.normal(15, 6, n), rng.integers(0, 4, n))
    a = infra_lob_metrics(pts, RECT, seed=4)
    perm = pts[rng.permutation(n)]
    b = infra_lob_metrics([perm[: n // 3], perm[n // 3:]], RECT, seed=4)
    assert a.to_json() == b.to_json()


def test_labels_filter_and_merge_several_clouds():
    road = grid_cloud(0.5)
    building = grid_cloud(0.5)
    building["label"] = BUILDING
    side = grid_cloud(1.0)
    side["label"] = SIDEWALK
    r = infra_lob_metrics([road, building, side], RECT, disks=50)
    assert r.n_points == 2400 + 600
    assert r.labels == ["road", "sidewalk"]
    r2 = infra_lob_metrics([road, building, side], RECT, labels="building", disks=50)
    assert r2.n_points == 2400
    assert resolve_labels("road, 2") == [1, 2]
    with pytest.raises(RLSError, match="unknown label"):
        resolve_labels("roadz")


def test_region_without_points_is_a_clear_error():
    far = cloud(np.array([100.0, 101.0]), np.array([100.0, 100.0]))
    with pytest.raises(RegionError, match="holds no points labelled road, sidewalk"):
        infra_lob_metrics(far, RECT)
    with pytest.raises(RegionError, match="2 points of other labels"):
        infra_lob_metrics(cloud(np.array([1.0, 2.0]), np.array([1.0, 1.0]), BUILDING), RECT)
    with pytest.raises(RegionError):
        infra_lob_metrics([], RECT)
    with pytest.raises(RegionError):
        infra_lob_metrics(empty_points(0), RECT)


@pytest.mark.parametrize(
    "poly",
    [
        [[0, 0], [1, 1]],
        [[0, 0], [1, 1], [2, 2]],
        [[0, 0], [0, 0], [0, 0], [0, 0]],
        [[0, 0], [1, 0], [0, 0]],
        [[0, 0], [1, float("nan")], [1, 1]],
        [1, 2, 3],
        [],
    ],
)
def test_degenerate_polygons_are_rejected(poly):
    with pytest.raises(RegionError):
        infra_lob_metrics(grid_cloud(1.0), poly)


def test_bad_parameters_are_region_errors():
    pts = grid_cloud(1.0)
    with pytest.raises(RegionError, match="radius"):
        infra_lob_metrics(pts, RECT, radius=0)
    with pytest.raises(RegionError, match="disk"):
        infra_lob_metrics(pts, RECT, disks=0)
    with pytest.raises(RegionError, match="cell"):
        infra_lob_metrics(pts, RECT, cell=-1)
    with pytest.raises(RegionError, match="too small"):
        infra_lob_metrics(pts, [[0, 0], [1, 0], [1, 1], [0, 1]], radius=0.7)  # no disk fits inside


def test_polygon_area_and_concave_point_in_polygon():
    # an L shape: the square [0,4]^2 minus [2,4]x[2,4]
    L = np.array([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]], dtype=float)
    assert polygon_area(L) == 12.0
    assert polygon_area(L[::-1]) == 12.0
    pts = np.array([[1, 1], [3, 1], [1, 3], [3, 3], [2.5, 2.5], [5, 1], [-1, 1], [1.9, 3.9], [3.9, 1.9]])
    np.testing.assert_array_equal(points_in_polygon(pts, L), [1, 1, 1, 0, 0, 0, 0, 1, 1])
    # a sampled grid: inside fraction equals the area fraction
    g = np.stack(np.meshgrid(np.arange(0.05, 4, 0.1), np.arange(0.05, 4, 0.1)), -1).reshape(-1, 2)
    assert points_in_polygon(g, L).sum() == 1200


def test_star_polygon_uses_even_odd_and_samples_inside():
    ang = np.linspace(0, 2 * np.pi, 10, endpoint=False)
    rad = np.where(np.arange(10) % 2 == 0, 10.0, 4.0)
    star = np.stack([rad * np.cos(ang), rad * np.sin(ang)], 1)
    rng = np.random.default_rng(0)
    s = sample_in_polygon(star, 500, rng, margin=0.5)
    assert points_in_polygon(s, star).all()
    assert len(s) == 500
    assert not points_in_polygon(np.array([[7.0, 3.0]]), star)[0]  # between two arms


def test_count_in_disks_matches_brute_force():
    rng = np.random.default_rng(5)
    xy = rng.uniform(-3, 3, (5000, 2))
    xy[:100] = np.round(xy[:100], 1)  # exact ties on disk boundaries
    c = np.round(rng.uniform(-3, 3, (400, 2)), 1)
    for r in (0.1, 0.7, 2.5):
        brute = (((xy[None] - c[:, None]) ** 2).sum(-1) <= r * r).sum(1)
        np.testing.assert_array_equal(count_in_disks(xy, c, r), brute)


def select_every_point(clouds, polygon, label_ids):
    """select_xy as it was: every point through the outline test, then the labels."""
    parts, inside_any = [], 0
    for pts in clouds:
        if len(pts) == 0:
            continue
        xy = np.stack([np.asarray(pts["x"], np.float64), np.asarray(pts["y"], np.float64)], 1)
        inside = points_in_polygon(xy, polygon)
        inside_any += int(inside.sum())
        parts.append(xy[inside & np.isin(pts["label"], np.asarray(label_ids))])
    return (np.concatenate(parts) if parts else np.empty((0, 2))), inside_any


@pytest.mark.parametrize("fields", [
    [("x", "<f8"), ("y", "<f8"), ("label", "<u4")],                  # a study's packed records
    [("label", "<u4"), ("y", "<f4"), ("x", "<f4"), ("z", "<f8")],    # float32, another order
    [("x", "<f8"), ("y", "<f8"), ("label", "<i8")]])                 # signed labels
@pytest.mark.parametrize("labels", [[1, 2], [3], [0, 2, 300], [70_000]])
def test_select_xy_equals_testing_every_point(fields, labels):
    """The same points, in the same order, and the same count inside the outline, as
    testing every point: on a concave outline, with points on its edges and vertices, on
    its bounding box, outside it, and labels from 0 to past the look-up table."""
    rng = np.random.default_rng(len(fields) + sum(labels))
    L = as_polygon([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]])
    clouds = []
    for n in (3000, 0, 500):
        xy = rng.uniform(-1, 5, (n, 2))
        xy[: n // 4] = np.round(xy[: n // 4] * 2) / 2  # on edges, vertices and the box
        pts = np.zeros(n, np.dtype(fields))
        pts["x"], pts["y"] = xy[:, 0], xy[:, 1]
        pts["label"] = rng.choice([0, 1, 2, 3, 300, 70_000], n)
        clouds.append(pts)
    got, got_any = select_xy(clouds, L, labels)
    want, want_any = select_every_point(clouds, L, labels)
    assert got_any == want_any and got.dtype == want.dtype and got.shape == want.shape
    assert np.array_equal(got, want) and len(got) > 0
    prepared, prepared_any = select_xy(clouds, L, labels, PreparedPolygon(L))
    assert prepared_any == want_any and np.array_equal(prepared, want)
    one, _ = select_xy(clouds[0], L, labels)
    assert np.array_equal(one, select_every_point(clouds[:1], L, labels)[0])
    lab = clouds[0]["label"]
    assert np.array_equal(label_mask(lab, labels), np.isin(lab, labels))


STAR = [[10 + (9 if i % 2 == 0 else 3) * np.cos(i * np.pi / 7),
         10 + (9 if i % 2 == 0 else 3) * np.sin(i * np.pi / 7)] for i in range(14)]


@pytest.mark.parametrize("offset", [0.0, 3.3e5, -7.1e6])
@pytest.mark.parametrize("outline", [RECT, [[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]], STAR,
                                     [[0, 0], [40, 0.5], [0.3, 1]]])  # thin and slanted
def test_a_prepared_polygon_answers_as_points_in_polygon(outline, offset):
    """Point for point, on random points, points on the edges and vertices (in or out
    by a rounding), on the grid's cell borders, far away and not finite."""
    rng = np.random.default_rng(len(outline))
    poly = as_polygon(outline) + offset
    region = PreparedPolygon(poly)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    span = hi - lo
    a, b = poly, np.roll(poly, -1, axis=0)
    t = rng.uniform(0, 1, (20_000, 1))
    k = rng.integers(0, len(poly), 20_000)
    on_edges = a[k] + t * (b[k] - a[k])
    nudged = on_edges + rng.choice([-1, 0, 1], (20_000, 2)) * 1e-12 * np.abs(on_edges).max()
    borders = region.lo + region.size * rng.integers(0, max(region.nx, region.ny), (5000, 2))
    xy = np.concatenate([rng.uniform(lo - span / 4, hi + span / 4, (30_000, 2)), on_edges,
                         nudged, borders, poly, [[np.nan, lo[1]], [lo[0], np.inf], [-1e300, 0]]])
    want = points_in_polygon(xy, poly)
    assert np.array_equal(region.contains(xy), want)
    assert want.sum() > 1000 and (region.state != 2).sum() > len(region.state) / 3
    rows = np.concatenate([xy[:5], xy[-3:]])
    assert np.array_equal(region.contains(rows), points_in_polygon(rows, poly))
    assert region.contains(np.empty((0, 2))).shape == (0,)


def test_infra_nuc_formula():
    assert infra_nuc([5, 5, 5], 10, 0.5) == 0.0
    # x = n / (N p) = [0, 2] -> mean 1, sd 1
    assert infra_nuc([0, 10], 10, 0.5) == 1.0


def test_one_infra_nuc_for_a_cloud_and_for_a_study_set():
    """The metrics command's InfraNUC of one cloud and the study's of a set of clouds
    are one formula: the same bits for the same counts (the study sums its members'
    counts first)."""
    from rls_addon.core.study.placement import set_metrics

    rng = np.random.default_rng(11)
    counts = rng.poisson(3.0, (6, 500))
    n = counts.sum(axis=1) + rng.integers(0, 400, 6)
    _, nuc = set_metrics(n, counts, 250.0, 0.0013)
    for row, k, got in zip(counts, n, nuc):
        assert infra_nuc(row, int(k), 0.0013) == got


def test_density_map_values_mask_and_png():
    L = as_polygon([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]])
    g = np.stack(np.meshgrid(np.arange(0.25, 4, 0.5), np.arange(0.25, 4, 0.5)), -1).reshape(-1, 2)
    g = g[points_in_polygon(g, L)]
    dm = density_map(g, L, cell_m=1.0)
    assert dm.values.shape == (4, 4)
    assert np.isnan(dm.values[2:, 2:]).all()
    finite = dm.values[np.isfinite(dm.values)]
    assert (finite == 4.0).all() and len(finite) == 12
    d = dm.to_dict()
    assert d["values"][3][3] is None and d["values"][0][0] == 4.0
    img = decode_png_rgba(dm.to_png(pixels_per_cell=2))
    assert img.shape == (8, 8, 4)
    assert (img[:4, 4:, 3] == 0).all()  # north-east quadrant outside: transparent
    assert (img[4:, :, 3] == 255).all()


def test_result_json_is_complete():
    r = infra_lob_metrics(grid_cloud(0.5), RECT, disks=200, seed=9, cell=5.0)
    d = json.loads(r.to_json())
    for key in ("infra_d", "infra_nuc", "n_points", "area_m2", "disks", "radius_m", "seed", "labels", "density"):
        assert key in d
    assert d["disks"] == 200 and d["seed"] == 9 and d["radius_m"] == 0.7
    assert d["density"]["shape"] == [6, 4]


def test_one_million_points_six_thousand_disks():
    """At scale (1e6 road and sidewalk points, the default 6,000 disks): every point of
    the region counted, InfraD the count over the area (600 m^2). Its time is
    make bench's to report, not a test's (a test never checks wall-clock time)."""
    rng = np.random.default_rng(0)
    n = 1_000_000
    pts = cloud(rng.uniform(0, 20, n), rng.uniform(0, 30, n), rng.integers(1, 3, n))
    r = infra_lob_metrics(pts, RECT)
    assert r.n_points == n and r.area_m2 == pytest.approx(600.0)
    assert r.infra_d == pytest.approx(n / 600.0)


def test_no_point_in_any_disk_is_an_error_not_perfect_uniformity():
    from rls_addon.core.errors import RegionError
    from rls_addon.core.metrics.infra import infra_nuc
    from rls_addon.core.study.placement import set_metrics

    with pytest.raises(RegionError, match="none of the 3 disks"):
        infra_nuc(np.zeros(3), 5, 0.01)
    d, nuc = set_metrics([5, 5], [[0, 0, 0], [1, 0, 2]], 100.0, 0.01)
    assert np.isnan(nuc[0]) and nuc[1] > 0


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_a_disk_seed_that_is_not_a_whole_number_from_0_is_a_region_error(seed):
    from rls_addon.core.study.placement import DiskLayout

    with pytest.raises(RegionError, match=r"^the disk seed must be a whole number >= 0, got "):
        infra_lob_metrics(grid_cloud(1.0), RECT, disks=10, seed=seed)
    with pytest.raises(RegionError, match=r"^the disk seed must be a whole number >= 0, got "):
        DiskLayout.make(RECT, disks=10, seed=seed)
    # a big seed is used whole: its disks are not seed 0's
    a = DiskLayout.make(RECT, disks=10, seed=2 ** 64).centres
    assert not np.array_equal(a, DiskLayout.make(RECT, disks=10, seed=0).centres)
