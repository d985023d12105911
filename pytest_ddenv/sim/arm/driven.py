"""`DrivenArm`: an arm in a loaded world, as one physics engine drives it (the arm's side of the engine
seam, sim/physics.py). `PybulletArm` (sim/arm/pybullet_arm.py) and `MujocoArm` (sim/mujoco/arm.py).

An engine's `spawn(robot, position, yaw)` returns one when `robot` is an `ArmRobot`. Link keys are the
engine's integers, named by `link_names`; the episode (sim/arm/episode.py) reads contacts through the
engine's `robot_contacts()` as for mobile robots.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]
"""(x, y, z, w)."""


class DrivenArm(Protocol):
    """One arm in one engine's world (see the module docstring)."""

    joint_names: tuple[str, ...]
    """The arm joints, base outwards (not the fingers)."""
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    """The arm joints' position limits (the URDF's)."""
    link_names: Mapping[int, str]
    """Link key -> link name, fingers included (-1: the base)."""
    finger_links: frozenset[int]
    """The link keys of the gripper's fingers."""
    max_opening: float
    """The widest gripper opening (m): the sum of the finger joints' upper limits."""

    def joint_state(self) -> tuple[list[float], list[float]]:
        """The arm joints' positions and velocities now."""

    def end_effector(self) -> tuple[Vector, Quaternion]:
        """The end-effector link's position and orientation now."""

    def gripper_opening(self) -> float:
        """The distance between the fingers now (m)."""

    def set_joint_targets(self, positions: Sequence[float]) -> None:
        """Position targets for the arm joints (clipped to the limits), held until the next call."""

    def set_gripper(self, action: str) -> None:
        """"open" (fingers to their upper limits) or "close" (fingers driven together at their effort limit)."""

    def inverse_kinematics(self, position: Vector, orientation: Quaternion) -> list[float]:
        """Arm joint positions that put the end effector at `position` with `orientation`, from the current
        joint positions (within the limits; the best found when it cannot be reached exactly)."""

    def self_contacts(self) -> list[tuple[int, int]]:
        """Pairs of the arm's own links touching now (non-adjacent links only)."""
