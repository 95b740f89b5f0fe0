"""A picture of a scanned cloud, so a newcomer sees a result without another tool:
a bird's-eye view and a perspective view of the points coloured by semantic label
with the sensor marked, and the bird's-eye view again coloured by intensity (with a
colour bar). World coordinates, metres. Needs matplotlib (imported here, lazily).
"""

import io
import math

import numpy as np

from ..errors import RLSError
from ..labels import DEFAULT_LABELS, label_name
from ..points import xyz
from .io.sidecar import points_to_world

MAX_POINTS = 60_000  # drawn at most (a seeded, even subsample of a bigger cloud)


def _plt():
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt
    except ImportError:
        raise RLSError("pictures of clouds need matplotlib: pip install matplotlib") from None
    return plt


def label_colours():
    """(20, 3) RGB of label ids 0..19, one distinct colour each (grey: unlabeled)."""
    table = np.array([
        [0.55, 0.55, 0.55], [0.30, 0.30, 0.34], [0.78, 0.62, 0.50], [0.85, 0.33, 0.10],
        [0.60, 0.45, 0.35], [0.70, 0.70, 0.25], [0.55, 0.35, 0.70], [0.95, 0.70, 0.10],
        [0.95, 0.30, 0.55], [0.20, 0.62, 0.25], [0.55, 0.75, 0.35], [0.10, 0.45, 0.90],
        [0.90, 0.10, 0.15], [0.35, 0.85, 0.95], [0.15, 0.35, 0.60], [0.65, 0.55, 0.40],
        [0.45, 0.45, 0.25], [0.80, 0.80, 0.85], [0.95, 0.45, 0.90], [0.75, 0.90, 0.80]])
    return table


def cloud_picture(points, info, title=None):
    """PNG bytes of ``points`` (``POINT_DTYPE``, the frame ``info`` says, a sidecar
    dict) as described in the module docstring."""
    plt = _plt()
    world = points_to_world(points, info, "the cloud")
    p = xyz(world)
    labels = np.asarray(points["label"], np.int64)
    inten = np.asarray(points["intensity"], np.float64)
    if len(p) > MAX_POINTS:
        keep = np.sort(np.random.default_rng(0).choice(len(p), MAX_POINTS, replace=False))
        p, labels, inten = p[keep], labels[keep], inten[keep]
    pose = np.asarray(info.get("sensor_pose_start", info.get("sensor_to_world", np.eye(4))))
    sensor = pose[:3, 3]
    colours = label_colours()
    col = colours[np.clip(labels, 0, len(colours) - 1)]
    fig = plt.figure(figsize=(16, 5.6))
    ax1 = fig.add_subplot(1, 3, 1)
    ax2 = fig.add_subplot(1, 3, 2, projection="3d")
    ax3 = fig.add_subplot(1, 3, 3)
    size = 0.6 if len(p) > 20_000 else 2.0
    ax1.scatter(p[:, 0], p[:, 1], c=col, s=size, linewidths=0)
    _sensor_mark(ax1, sensor, pose)
    ax1.set_title("bird's-eye view, coloured by label")
    present = [int(i) for i in np.unique(labels) if 0 <= i < len(colours)]
    handles = [plt.Line2D([], [], marker="o", ls="", color=colours[i],
                          label=f"{i} {label_name(i)}") for i in present]
    handles.append(plt.Line2D([], [], marker="^", ls="", color="red", markeredgecolor="black",
                              label="sensor"))
    ax1.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=3,
               fontsize=7, frameon=False)
    ax2.scatter(p[:, 0], p[:, 1], p[:, 2], c=col, s=size * 0.6, linewidths=0)
    ax2.scatter([sensor[0]], [sensor[1]], [sensor[2]], marker="^", s=80, c="red",
                edgecolors="black")
    ax2.view_init(elev=28, azim=-60)
    ax2.set_title("perspective view, coloured by label")
    ax2.set_xlabel("x (m)")
    ax2.set_ylabel("y (m)")
    ax2.set_zlabel("z (m)")
    _equal_3d(ax2, p)
    sc = ax3.scatter(p[:, 0], p[:, 1], c=inten, cmap="viridis", vmin=0.0, vmax=1.0, s=size,
                     linewidths=0)
    _sensor_mark(ax3, sensor, pose)
    ax3.set_title("bird's-eye view, coloured by intensity")
    fig.colorbar(sc, ax=ax3, label="intensity (0..1, reflectivity x cos incidence)")
    for ax in (ax1, ax3):
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.25)
    device = info.get("device", {}).get("name", "")
    fig.suptitle(title or f"{info.get('sensor', 'LiDAR')} ({device}), frame "
                          f"{info.get('frame', '?')}: {len(points)} points, world frame")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _sensor_mark(ax, sensor, pose):
    ax.plot([sensor[0]], [sensor[1]], marker="^", color="red", markersize=10,
            markeredgecolor="black", zorder=5)
    heading = math.atan2(pose[1, 0], pose[0, 0])
    ax.annotate("", xy=(sensor[0] + 4 * math.cos(heading), sensor[1] + 4 * math.sin(heading)),
                xytext=(sensor[0], sensor[1]),
                arrowprops={"arrowstyle": "->", "color": "red", "lw": 1.5}, zorder=5)


def _equal_3d(ax, p):
    """Axes on the data's own ranges, one metre as long on each (a flat street stays
    flat), with at least a little height so the view is readable."""
    if not len(p):
        return
    lo, hi = p.min(0), p.max(0)
    span = np.maximum(hi - lo, 1e-3)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect((span[0], span[1], max(span[2], 0.12 * max(span[0], span[1]))))
    from matplotlib.ticker import MaxNLocator

    ax.zaxis.set_major_locator(MaxNLocator(3))


assert len(label_colours()) == len(DEFAULT_LABELS)
