"""Pose algebra for SDF frames: inverse and relative poses on top of `Pose.compose`."""

from __future__ import annotations

import numpy as np

from pytest_ddenv.world import geometry
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.model import Pose

IDENTITY = Pose()


def from_matrix(position: FloatArray, rotation: FloatArray) -> Pose:
    roll, pitch, yaw = geometry.rpy_from_matrix(rotation)
    return Pose(float(position[0]), float(position[1]), float(position[2]), roll, pitch, yaw)


def inverse(pose: Pose) -> Pose:
    rotation = pose.rotation.T
    return from_matrix(-rotation @ pose.position, rotation)


def relative(anchor: Pose, pose: Pose) -> Pose:
    """`pose` (in the world) expressed in the frame `anchor` (in the world): anchor⁻¹ ∘ pose."""
    if anchor == pose:
        return IDENTITY
    if anchor == IDENTITY:
        return pose
    return inverse(anchor).compose(pose)


def from_quaternion(x: float, y: float, z: float, qx: float, qy: float, qz: float, qw: float) -> Pose:
    norm = float(np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw))
    if norm == 0.0:
        raise ValueError("the quaternion has zero length")
    qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
    rotation = np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )
    return from_matrix(np.array([x, y, z]), rotation)
