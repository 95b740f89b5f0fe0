"""Boxes between a LiDAR's frame of reference and RLS's world frame.

A box in a frame is OpenPCDet's ``x y z dx dy dz heading``: its centre (the box's
middle) in that frame, its length (along its heading), width and height, and the
heading, counter-clockwise about the frame's z axis from its x axis. That is what
RLS's ``kitti`` labels hold (``datasets/kitti.py``), in the sensor frame or with
``--level`` in the gravity-aligned frame at the sensor; ``frame_to_world`` (4x4, the
meta's ``frame_to_world``) maps the frame to the world.

Objects stand upright in the world. In a frame tilted from level (a pitched sensor
without ``--level``) an upright box is tilted too, and its label keeps only the
heading its length axis shows in the frame (``datasets.common.heading_in``: the
azimuth of that axis in the frame's x-y plane). ``to_world`` inverts exactly that:
the world yaw is the one of the horizontal direction whose azimuth in the frame is the
heading (the world yaw of ``frame_to_world`` applied to (cos h, sin h, t), t chosen so
the direction is horizontal). In a level frame this is the heading plus the frame's
yaw. Sizes do not change; the centre maps as a point."""

import numpy as np


def _rt(frame_to_world):
    m = np.asarray(frame_to_world, np.float64).reshape(4, 4)
    return m[:3, :3], m[:3, 3]


def world_yaw(frame_to_world, heading):
    """(N,) world yaw of upright boxes whose heading in the frame is ``heading``."""
    r, _ = _rt(frame_to_world)
    h = np.asarray(heading, np.float64).reshape(-1)
    c, s = np.cos(h), np.sin(h)
    rz = r[2]
    if abs(rz[2]) > 1e-9:
        t = -(rz[0] * c + rz[1] * s) / rz[2]
    else:  # the frame's z axis is horizontal: no horizontal direction has an azimuth
        t = np.zeros_like(h)
    d = np.stack([c, s, t], 1) @ r.T
    return np.arctan2(d[:, 1], d[:, 0])


def frame_heading(frame_to_world, yaw):
    """(N,) heading in the frame of upright world boxes of world yaw ``yaw``: the
    azimuth of their length axis there (``datasets.common.heading_in``)."""
    r, _ = _rt(frame_to_world)
    y = np.asarray(yaw, np.float64).reshape(-1)
    d = np.stack([np.cos(y), np.sin(y), np.zeros_like(y)], 1) @ r  # r.T @ d, row-wise
    return np.arctan2(d[:, 1], d[:, 0])


def to_world(boxes, frame_to_world):
    """(N, 7) world boxes of (N, 7) boxes ``x y z dx dy dz heading`` in the frame."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    r, t = _rt(frame_to_world)
    out = b.copy()
    out[:, :3] = b[:, :3] @ r.T + t
    out[:, 6] = world_yaw(frame_to_world, b[:, 6])
    return out


def to_frame(boxes, frame_to_world):
    """(N, 7) boxes in the frame of (N, 7) world boxes (the inverse of ``to_world``)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    r, t = _rt(frame_to_world)
    out = b.copy()
    out[:, :3] = (b[:, :3] - t) @ r
    out[:, 6] = frame_heading(frame_to_world, b[:, 6])
    return out


__all__ = ["frame_heading", "to_frame", "to_world", "world_yaw"]
