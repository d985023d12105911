"""Rigid transforms and point-to-primitive distances, vectorised with numpy.

Conventions (the same as URDF and SDF): a pose is x y z roll pitch yaw, the rotation is
R = Rz(yaw) @ Ry(pitch) @ Rx(roll), and a point p in a frame with pose (t, R) is t + R @ p in the parent.
Cylinders have their axis along their local z.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def rotation_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """The 3x3 rotation of the fixed-axis roll-pitch-yaw angles (Rz @ Ry @ Rx)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_matrix(rotation: FloatArray) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a rotation matrix (inverse of `rotation_matrix`)."""
    pitch = float(np.arcsin(np.clip(-rotation[2, 0], -1.0, 1.0)))
    if abs(rotation[2, 0]) < 1.0 - 1e-12:
        roll = float(np.arctan2(rotation[2, 1], rotation[2, 2]))
        yaw = float(np.arctan2(rotation[1, 0], rotation[0, 0]))
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = float(np.arctan2(-rotation[0, 1], rotation[1, 1]))
    return roll, pitch, yaw


def to_local(points: FloatArray, translation: FloatArray, rotation: FloatArray) -> FloatArray:
    """Express world points (N, 3) in a frame whose pose in the world is (translation, rotation)."""
    return (points - translation) @ rotation


def box_distance(local_points: FloatArray, size: FloatArray) -> FloatArray:
    """Distance from points (in the box frame) to a centred box of full `size`; 0 inside."""
    excess = np.maximum(np.abs(local_points) - size / 2.0, 0.0)
    return np.linalg.norm(excess, axis=1)


def cylinder_distance(local_points: FloatArray, radius: float, length: float) -> FloatArray:
    """Distance from points (in the cylinder frame) to a centred z-axis cylinder; 0 inside."""
    radial = np.hypot(local_points[:, 0], local_points[:, 1]) - radius
    axial = np.abs(local_points[:, 2]) - length / 2.0
    return np.hypot(np.maximum(radial, 0.0), np.maximum(axial, 0.0))


def sphere_distance(local_points: FloatArray, radius: float) -> FloatArray:
    """Distance from points (in the sphere frame) to a centred sphere; 0 inside."""
    return np.maximum(np.linalg.norm(local_points, axis=1) - radius, 0.0)


def box_corners(size: FloatArray) -> FloatArray:
    """The 8 corners (8, 3) of a centred box of full `size`."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    return signs * (size / 2.0)


def cylinder_extent_points(radius: float, length: float, segments: int = 32) -> FloatArray:
    """Points on the rims of a z-axis cylinder, enough for tight axis-aligned bounds after rotation."""
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    top = np.column_stack([ring, np.full(segments, length / 2.0)])
    bottom = np.column_stack([ring, np.full(segments, -length / 2.0)])
    return np.vstack([top, bottom])
