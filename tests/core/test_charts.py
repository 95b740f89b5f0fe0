"""Density charts (``core/metrics/charts.py``) of ``rls metrics --density-png`` and of the study's
``density_k<K>.png``: axes in metres, a labelled colour scale, a title with the metrics,
one colour scale for every k of a study, and the bare image when matplotlib is missing."""

import struct
import sys

import numpy as np
import pytest

from rls_addon.core.metrics import charts
from rls_addon.core.metrics.infra import infra_lob_metrics
from rls_addon.core.points import empty_points

from .external_tools import require_module


@pytest.fixture(autouse=True, scope="module")
def _matplotlib():
    require_module("matplotlib", "matplotlib==3.11.2")


# an L-shaped region: its bounding box holds a 2 x 2 m corner of cells outside it
L_REGION = [[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]]


def l_cloud():
    g = np.stack(np.meshgrid(np.arange(0.25, 4, 0.5), np.arange(0.25, 4, 0.5)), -1).reshape(-1, 2)
    g = g[~((g[:, 0] > 2) & (g[:, 1] > 2))]
    g = np.concatenate([g, [[0.5, 0.5]] * 4])  # one denser cell: the scale runs 0 to 8
    p = empty_points(len(g))
    p["x"], p["y"], p["label"] = g[:, 0] + 100.0, g[:, 1] - 50.0, 1
    return p


@pytest.fixture
def l_result():
    poly = [[x + 100.0, y - 50.0] for x, y in L_REGION]
    return infra_lob_metrics([l_cloud()], poly, disks=50, cell=1.0)


def no_matplotlib(monkeypatch):
    for name in ("matplotlib", "matplotlib.pyplot"):
        monkeypatch.setitem(sys.modules, name, None)  # `import matplotlib` now fails


def test_density_chart_has_metre_axes_unit_colorbar_and_title(l_result):
    dm = l_result.density
    title = charts.density_title("Lidar.001, region L", l_result.infra_d, l_result.infra_nuc)
    fig = charts.density_figure(dm, title, polygon=l_result.polygon_xy,
                                sensors=[("Lidar.001", 99.0, -51.0, 45.0)])
    try:
        ax = fig.axes[0]
        assert ax.get_xlabel() == "x (m, world)" and ax.get_ylabel() == "y (m, world)"
        (im,) = ax.get_images()
        # cells at their world coordinates, not at pixel indices
        assert im.get_extent() == pytest.approx([100.0, 104.0, -50.0, -46.0])
        assert im.get_clim() == (0.0, 8.0)
        cbar = im.colorbar
        assert cbar is not None and "points / m²" in cbar.ax.get_ylabel()
        assert "1 m cells" in cbar.ax.get_ylabel()
        text = fig.get_suptitle()
        assert "Lidar.001" in text and f"InfraD {l_result.infra_d:.2f} points / m²" in text
        assert f"InfraNUC {l_result.infra_nuc:.3f}" in text
        # cells outside the region carry no data: masked (drawn grey), not zero
        data = im.get_array()
        assert data.mask[2:, 2:].all() and not data.mask[:2, :].any()
        assert im.get_cmap().get_bad()[:3] == pytest.approx(ax.get_facecolor()[:3])
        assert ax.get_facecolor()[:3] != pytest.approx(im.get_cmap()(0.0)[:3])
        legend = " ".join(t.get_text() for t in fig.legends[0].get_texts())
        assert "outside the region" in legend and "sensor" in legend
        # the sensor west of the region is inside the plotted area
        assert ax.get_xlim()[0] < 99.0
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_density_png_is_a_deterministic_chart(l_result):
    a, notice = charts.density_png(l_result.density, "t", polygon=l_result.polygon_xy)
    b, _ = charts.density_png(l_result.density, "t", polygon=l_result.polygon_xy)
    assert notice is None and a == b and a[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"Software" not in a and b"matplotlib" not in a
    width, _ = struct.unpack(">II", a[16:24])  # IHDR
    assert width == 750  # a 7.5 in figure at 100 dpi, not the 4 x 4 cell grid


def test_density_png_without_matplotlib_is_the_bare_map_and_a_notice(monkeypatch, l_result):
    no_matplotlib(monkeypatch)
    assert charts.pyplot() is None
    png, notice = charts.density_png(l_result.density, "t", polygon=l_result.polygon_xy)
    assert png == l_result.density.to_png()
    assert "matplotlib is not installed" in notice and "\n" not in notice


def test_density_scale_spans_all_maps():
    from rls_addon.core.metrics.infra import DensityMap

    a = DensityMap((0, 0), 1.0, np.array([[1.0, np.nan], [3.0, 0.0]]))
    b = DensityMap((0, 0), 1.0, np.array([[7.5, 2.0], [np.nan, np.nan]]))
    empty = DensityMap((0, 0), 1.0, np.array([[0.0, np.nan]]))
    assert charts.density_scale([a, b]) == (0.0, 7.5)
    assert charts.density_scale([a]) == (0.0, 3.0)
    assert charts.density_scale([empty]) == (0.0, 1.0)


@pytest.fixture(scope="module")
def study():
    from rls_addon.core.casting import NumpyCaster
    from rls_addon.core.study.config import StudyConfig
    from rls_addon.core.study.loop import run_study

    from .test_study import FakeStudyScene

    cfg = StudyConfig(device="generic_uniform32", k=(1, 2), disks=200, noise=False,
                      dropout=False)
    return run_study(FakeStudyScene(), cfg, factory=lambda name: (NumpyCaster, None))


def test_study_density_maps_share_one_scale(study, monkeypatch):
    from rls_addon.core.study import report

    maps, scale = report.density_maps(study)
    assert set(maps) == {1, 2}
    own = {k: float(np.nanmax(dm.values)) for k, dm in maps.items()}
    assert own[1] != own[2]  # each map's own maximum differs: a shared scale matters
    assert scale == (0.0, max(own.values()))

    drawn = {}
    real = charts.figure_png

    def capture(fig):
        title = fig.get_suptitle()
        if "best set of k" in title:
            (im,) = fig.axes[0].get_images()
            k = int(title.split("best set of k = ")[1].split(":")[0])
            drawn[k] = (im.get_clim(), im.colorbar.ax.get_ylabel(), title,
                        fig.axes[0].get_xlabel())
        return real(fig)

    monkeypatch.setattr(charts, "figure_png", capture)
    files, notice = report.charts_png(study)
    assert notice is None
    assert {"pareto.png", "density_k1.png", "density_k2.png"} <= set(files)
    assert set(drawn) == {1, 2}
    names = [c.name for c in study.candidates]
    for k, (clim, label, title, xlabel) in drawn.items():
        assert clim == pytest.approx(scale)
        assert "points / m²" in label and "one scale for k = 1, 2" in label
        assert f"0 to {scale[1]:.3g}" in label
        best = study.searches[k].best
        assert study.scene in title and f"InfraD {best.infra_d:.2f}" in title
        assert all(names[i] in title for i in best.members)
        assert xlabel == "x (m, world)"


def test_study_charts_without_matplotlib_fall_back_to_bare_maps(study, monkeypatch):
    from rls_addon.core.study import report

    no_matplotlib(monkeypatch)
    files, notice = report.charts_png(study)
    assert set(files) == {"density_k1.png", "density_k2.png"}
    assert files["density_k2.png"] == study.density(study.searches[2].best.members).to_png()
    assert "matplotlib is not installed" in notice and "pareto.png skipped" in notice
