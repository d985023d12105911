"""`DrivenArm`: an arm in a loaded world, as one physics engine drives it (the arm's side of the engine
seam, sim/physics.py). `PybulletArm` (sim/arm/pybullet_arm.py) and `MujocoArm` (sim/mujoco/arm.py).

How the episode gets it: an engine's `spawn(robot, position, yaw)`, given an `ArmRobot` (sim/arm/robot.py),
returns `(driven, body)` as for any robot, and `driven.arm` is the `DrivenArm` (the arm joints at the
robot's `home`, the gripper open, both held by their position controllers). PyBullet: `ArmRobot.spawn`
sets its own `arm` to a `PybulletArm` and the engine returns the `ArmRobot` itself; MuJoCo returns its own
driven robot with `arm` set to a `MujocoArm`. `ArmEpisode` (sim/arm/episode.py) reads `driven.arm` and
nothing else of the robot but `name`, `footprint` and `link_names`.

Link keys are the engine's integers, named by `link_names`; the episode reads contacts through the
engine's `robot_contacts()` as for mobile robots (a self contact, whose other body is the arm, is left out
there: `self_contacts()` reports those). An arm may also offer `end_effector_velocity() -> (linear,
angular)` (world frame; the run records zeros for an arm without it) and `camera_image(camera, colors) -> image`
(the scenario's `Camera`'s picture, as `ArmObservation.image` describes it, `colors` the models' RGBA by
body key; without it a scenario with a camera is refused).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]
"""(x, y, z, w)."""
CAMERA_NEAR, CAMERA_FAR = 0.01, 10.0
"""m: a declared camera's clipping planes in every engine (depth beyond the far one reads as CAMERA_FAR)."""


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
