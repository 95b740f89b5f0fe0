"""Poses between Blender's frame and CARLA's, as OPV2V/OpenCOOD store them.

Blender's world is right-handed (x, y, z with z up); CARLA's (Unreal's) is left-handed
with x forward, y right, z up. A point maps by mirroring y: (x, y, z) -> (x, -y, z);
a pose M (4x4, Blender) maps to S M S with S = diag(1, -1, 1, 1), which keeps a
rotation a rotation (det S M S = det M).

OpenCOOD reads a pose as ``[x, y, z, roll, yaw, pitch]`` (metres, degrees) and builds
its matrix in ``opencood/utils/transformation_utils.py:x_to_world``: the x axis is
(cos p cos y, sin y cos p, sin p) and so on. ``carla_pose`` inverts exactly that
construction, so ``carla_matrix(carla_pose(M)) == S M S``.
"""

import math

import numpy as np

from ...scene.motion import polar

MIRROR = np.diag([1.0, -1.0, 1.0, 1.0])


def to_carla_points(xyz):
    """(N, 3) points from Blender's axes to CARLA's (y mirrored)."""
    out = np.array(xyz, np.float64, copy=True).reshape(-1, 3)
    out[:, 1] *= -1.0
    return out


def carla_matrix(pose):
    """4x4 CARLA matrix of ``[x, y, z, roll, yaw, pitch]`` (OpenCOOD's x_to_world)."""
    x, y, z, roll, yaw, pitch = (float(v) for v in pose)
    cy, sy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    m[0, :3] = (cp * cy, cy * sp * sr - sy * cr, -cy * sp * cr - sy * sr)
    m[1, :3] = (sy * cp, sy * sp * sr + cy * cr, -sy * sp * cr + cy * sr)
    m[2, :3] = (sp, -cp * sr, cp * cr)
    return m


def carla_pose(matrix):
    """``[x, y, z, roll, yaw, pitch]`` (CARLA, metres and degrees) of a Blender 4x4 pose
    (scale removed)."""
    m = MIRROR @ np.asarray(matrix, np.float64) @ MIRROR
    r = polar(m[None, :3, :3])[0][0]
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, r[2, 0]))))
    yaw = math.degrees(math.atan2(r[1, 0], r[0, 0]))
    roll = math.degrees(math.atan2(-r[2, 1], r[2, 2]))
    return [float(m[0, 3]), float(m[1, 3]), float(m[2, 3]), roll, yaw, pitch]


def blender_matrix(pose):
    """The Blender 4x4 pose of a CARLA ``[x, y, z, roll, yaw, pitch]``."""
    return MIRROR @ carla_matrix(pose) @ MIRROR
