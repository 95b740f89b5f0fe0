"""Foreground: what of one still sensor's frame is not its background.

``learn_background`` keeps, per sensor, its range-image background (``background.py``)
learned from sweeps (the scene without road users, or frames with traffic), its pose, and
the ground read from its own background returns (``ground.py``). ``foreground`` takes a
frame's returns that are nearer than every background mode of their cell (with 2 of 8
neighbours foreground too), and those in cells that never had a background when they are
plausibly an object: between 0.3 m below and ``max_height`` above the ground near them
and within ``max_range`` of the sensor. They are kept in the world frame, with the pixel
each came from (to merge fragments that touch in the range image)."""

from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from .background import BackgroundModel
from .ground import GroundGrid


@dataclass
class SensorBackground:
    """What the roadside detector learned of one still sensor (sensor -> world ``pose``
    (4, 4)): its range-image ``model``, the world points of its background within reach
    (``ground_points``, (M, 3)) and the ground grid made from them."""

    sensor: str
    model: BackgroundModel
    pose: np.ndarray
    ground_points: np.ndarray
    ground: GroundGrid

    @property
    def sweeps(self):
        return self.model.frames


@dataclass
class SensorView:
    """One frame of one sensor as the roadside detector keeps it: its foreground's world
    points (M, 3) and the range-image pixel of each (M,) (``RangeImageGrid.pixel_of``)."""

    xyz: np.ndarray
    pixel: np.ndarray


def learn_background(p, sensor, sweeps, pose):
    """``SensorBackground`` of ``sensor`` at ``pose`` learned from ``sweeps`` (a list of
    sensor-frame point arrays, ``background.sensor_xyz_ring``) with the detector's
    parameters ``p``."""
    model = BackgroundModel.learn(list(sweeps), margin=p.margin, min_support=p.min_support,
                                  persist_support=p.persist_support,
                                  steady_support=p.steady_support, max_modes=p.max_modes,
                                  azimuth_res_deg=p.azimuth_res_deg)
    pts = model.background_xyz()
    pts = pts[np.linalg.norm(pts, axis=1) <= p.max_range]
    world = pts @ pose[:3, :3].T + pose[:3, 3]
    return SensorBackground(str(sensor), model, pose, world,
                            GroundGrid(world, reach=p.ground_reach, default=p.ground_z))


def check_still(background, pose, tolerance):
    """``InputError`` when ``pose`` is farther than ``tolerance`` (m, rad) from where the
    background was learned: the detector is for still sensors."""
    learned = background.pose
    moved = np.linalg.norm(pose[:3, 3] - learned[:3, 3])
    turn = np.arccos(np.clip((np.trace(pose[:3, :3].T @ learned[:3, :3]) - 1) / 2, -1, 1))
    if moved > tolerance[0] or turn > tolerance[1]:
        raise InputError(f"sensor {background.sensor!r} is {moved:.3f} m and "
                         f"{np.degrees(turn):.2f} deg from where its background was learned: "
                         "the detector is for still sensors (learn again for the new pose)")


def foreground(p, background, points, pose):
    """``SensorView`` of a frame's ``points`` (sensor frame) against ``background``."""
    check_still(background, pose, p.pose_tolerance)
    model = background.model
    fg, empty, xyz, cell = model.foreground(points, p.min_neighbours)
    cand = fg | empty
    local = xyz[cand]
    w = local @ pose[:3, :3].T + pose[:3, 3]
    h = w[:, 2] - background.ground.height_at(w[:, :2])
    keep = (h > -0.3) & (h < p.max_height) & (np.linalg.norm(local, axis=1) <= p.max_range)
    return SensorView(w[keep], model.grid.pixel_of(cell[cand][keep]))
