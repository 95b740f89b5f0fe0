"""Density-map charts a reader can read: axes in metres, a labelled colour scale, a title.

Used by ``rls metrics --density-png`` and by the placement study's ``density_k<K>.png``.
matplotlib is imported only when a chart is drawn (Agg backend, no window); without it
the callers fall back to the bare image of ``DensityMap.to_png`` and say so. Output is
deterministic: the PNG carries no software/version text.

A chart shows ``DensityMap.values`` (points per m^2 in square cells, row 0 the southern
row) at the cells' world coordinates; cells whose centre is outside the region hold no
data and are drawn grey, like the background, so they cannot be read as zero. A cell
inside the region with no return at all is drawn white (``NO_RETURNS_COLOUR``, in the
legend), apart from the scale, so an empty cell is never read as a sparse one (the
bottom colour of the scale is "a few points", not "none").
"""

import io
import math
import textwrap

import numpy as np

DENSITY_UNIT = "points / m²"
NO_DATA_COLOUR = "#d4d4d4"
NO_RETURNS_COLOUR = "#ffffff"
CMAP = "viridis"
DPI = 100

MATPLOTLIB_MISSING = "matplotlib is not installed"


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend, or None when matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def density_scale(maps):
    """(vmin, vmax) for one colour scale over all ``maps``: 0 to the largest finite cell
    value of any of them (1 when none has a point)."""
    top = 0.0
    for dm in maps:
        v = np.asarray(dm.values, dtype=np.float64)
        finite = v[np.isfinite(v)]
        if finite.size:
            top = max(top, float(finite.max()))
    return 0.0, (top if top > 0 else 1.0)


def density_title(subject, infra_d, infra_nuc, detail=None):
    """Two lines: what is shown, then InfraD / InfraNUC (and ``detail``)."""
    second = f"InfraD {infra_d:.2f} {DENSITY_UNIT}, InfraNUC {infra_nuc:.3f}"
    if detail:
        second += f" ({detail})"
    return "\n".join(textwrap.wrap(subject, 90) + textwrap.wrap(second, 90))


def density_figure(dm, title, *, polygon=None, sensors=(), scale=None, scale_note=None,
                   plt=None):
    """A matplotlib figure of the ``DensityMap`` ``dm``.

    ``polygon``: the region outline (N, 2) in world xy, drawn in black.
    ``sensors``: (name, x, y, heading_deg or None) marked with a red triangle, the
    name and, when a heading is given, an arrow along it.
    ``scale``: (vmin, vmax) of the colour scale (default ``density_scale([dm])``);
    ``scale_note`` is added to the colour bar's label (e.g. that the scale is shared).
    The figure is the caller's to save (``figure_png``) or close.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    plt = plt or pyplot()
    vmin, vmax = scale if scale is not None else density_scale([dm])
    ny, nx = dm.values.shape
    x0, y0 = dm.origin_xy
    c = dm.cell_m
    extent = [x0, x0 + nx * c, y0, y0 + ny * c]
    lo = np.array([extent[0], extent[2]], float)
    hi = np.array([extent[1], extent[3]], float)
    for _, x, y, _ in sensors:
        lo = np.minimum(lo, [x, y])
        hi = np.maximum(hi, [x, y])
    pad = max(1.0, 0.03 * float((hi - lo).max()))
    lo, hi = lo - pad, hi + pad
    span = hi - lo
    aspect = float(span[1] / span[0]) if span[0] > 0 else 1.0
    # a plot about 5.3 in wide; below it ticks, x label and legend, above it the title
    lines = title.count("\n") + 1
    height = min(10.0, max(3.8, 5.3 * aspect + 1.0 + 0.22 * lines))
    fig, ax = plt.subplots(figsize=(7.5, height), layout="constrained")
    ax.set_facecolor(NO_DATA_COLOUR)
    # cells with no return are put below the scale and drawn in its "under" colour
    values = np.asarray(dm.values, dtype=np.float64)
    empty = np.isfinite(values) & (values == 0)
    shown = np.where(empty, vmin - 1.0, values)
    cmap = plt.get_cmap(CMAP).with_extremes(bad=NO_DATA_COLOUR, under=NO_RETURNS_COLOUR)
    im = ax.imshow(np.ma.masked_invalid(shown), origin="lower", extent=extent, cmap=cmap,
                   vmin=vmin, vmax=vmax, interpolation="nearest")
    label = f"density ({DENSITY_UNIT}, {c:g} m cells)"
    if scale_note:
        label += f"\n{scale_note}"
    cax = ax.inset_axes([1.03, 0.0, 0.035, 1.0])  # exactly as tall as the map
    fig.colorbar(im, cax=cax, label=label)
    handles = [Patch(facecolor=NO_DATA_COLOUR, edgecolor="0.5", label="no data (outside the region)")]
    if empty.any():
        handles.append(Patch(facecolor=NO_RETURNS_COLOUR, edgecolor="0.5",
                             label="no returns (0 points)"))
    if polygon is not None:
        poly = np.asarray(polygon, dtype=np.float64)
        poly = np.vstack([poly, poly[:1]])
        ax.plot(poly[:, 0], poly[:, 1], color="black", lw=1.2)
        handles.append(Line2D([], [], color="black", lw=1.2, label="region outline"))
    for name, x, y, heading in sensors:
        ax.plot([x], [y], marker="^", color="red", markersize=9, markeredgecolor="black",
                linestyle="none")
        right = x > (lo[0] + hi[0]) / 2  # label towards the middle, not off the plot
        ax.annotate(name, (x, y), textcoords="offset points", xytext=(-5 if right else 5, 5),
                    ha="right" if right else "left", fontsize=7, color="darkred",
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                          "alpha": 0.8})
        if heading is not None:
            a = math.radians(heading)
            ax.annotate("", xy=(x + 2 * math.cos(a), y + 2 * math.sin(a)), xytext=(x, y),
                        arrowprops={"arrowstyle": "->", "color": "red", "lw": 1.5})
    if sensors:
        handles.append(Line2D([], [], marker="^", color="red", markeredgecolor="black",
                              linestyle="none", markersize=8, label="sensor"))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, world)")
    ax.set_ylabel("y (m, world)")
    fig.suptitle(title, fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    return fig


def sensor_marker(name, sensor_to_world):
    """(name, x, y, heading_deg) of a sensor at the 4x4 ``sensor_to_world`` for
    ``density_figure``: its position and the way its +X axis points seen from above
    (None when it points straight up or down); None for a matrix that is not a finite
    4x4."""
    try:
        m = np.asarray(sensor_to_world, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        return None
    forward = m[:2, 0]
    heading = (float(np.degrees(np.arctan2(forward[1], forward[0])))
               if np.hypot(*forward) > 1e-9 else None)
    return (name, float(m[0, 3]), float(m[1, 3]), heading)


def figure_png(fig, dpi=DPI):
    """PNG bytes of ``fig`` (no software text, so the bytes repeat); closes the figure."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def density_png(dm, title, **kwargs):
    """(PNG bytes, notice): the chart of ``density_figure``, or, without matplotlib,
    the bare image of ``dm.to_png()`` and a one-line notice saying so."""
    plt = pyplot()
    if plt is None:
        return dm.to_png(), (f"{MATPLOTLIB_MISSING}: the density map is written without "
                             "axes, scale or title (pip install matplotlib)")
    return figure_png(density_figure(dm, title, plt=plt, **kwargs)), None
