"""InfraLOB metrics: exactness, stability and the failure modes."""

import json
import math

import numpy as np
import pytest

from rls_addon.core.errors import RegionError, RLSError
from rls_addon.core.metrics import (
    count_in_disks,
    density_map,
    infra_lob_metrics,
    infra_nuc,
    resolve_labels,
)
from rls_addon.core.png import decode_png_rgba
from rls_addon.core.points import empty_points
from rls_addon.core.polygon import as_polygon, points_in_polygon, polygon_area, sample_in_polygon

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


def test_infra_nuc_formula():
    assert infra_nuc([5, 5, 5], 10, 0.5) == 0.0
    # x = n / (N p) = [0, 2] -> mean 1, sd 1
    assert infra_nuc([0, 10], 10, 0.5) == 1.0


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


def test_speed_one_million_points_six_thousand_disks():
    import time

    rng = np.random.default_rng(0)
    n = 1_000_000
    pts = cloud(rng.uniform(0, 20, n), rng.uniform(0, 30, n), rng.integers(1, 3, n))
    t0 = time.perf_counter()
    infra_lob_metrics(pts, RECT)
    elapsed = time.perf_counter() - t0
    print(f"1e6 points, 6000 disks: {elapsed:.2f} s")
    assert elapsed < 5.0  # about 0.5-1 s on a laptop; generous for CI


def test_no_point_in_any_disk_is_an_error_not_perfect_uniformity():
    from rls_addon.core.errors import RegionError
    from rls_addon.core.metrics import infra_nuc
    from rls_addon.core.placement import set_metrics

    with pytest.raises(RegionError, match="none of the 3 disks"):
        infra_nuc(np.zeros(3), 5, 0.01)
    d, nuc = set_metrics([5, 5], [[0, 0, 0], [1, 0, 2]], 100.0, 0.01)
    assert np.isnan(nuc[0]) and nuc[1] > 0
