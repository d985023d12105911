"""`ArmState`: what an arm's failure predicates see at one control tick (the arm's `RobotState`).

An arm's run is recorded like a mobile robot's, with the end effector in the place of the base: `pose` is
the end effector's pose, so `signature()`, "same failure" (where it happened, what was touched) and the
trajectory-guided reduction work unchanged. Nothing of the simulation here; docs/oracle.md lists the arm
predicates (oracle/arm_predicates.py).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from pytest_ddenv.oracle.predicates import GROUND, Contact, History

Pose6 = tuple[float, float, float, float, float, float]
"""(x, y, z, roll, pitch, yaw), world frame."""

GRIPPER_OPEN = "open"
GRIPPER_CLOSE = "close"


@dataclass(frozen=True)
class ArmState:
    """What an arm predicate sees at one control tick (world frame, SI units).

    - `time`, `timeout`: simulated seconds since the start, and the run's limit.
    - `pose`: the end effector's (x, y, z, roll, pitch, yaw); `history`: its positions at every tick so far.
    - `joint_positions`, `joint_velocities`: the arm joints' (rad or m), in the arm's joint order, with
      `joint_names`, `joint_lower`, `joint_upper` (the URDF's limits).
    - `gripper_opening`: the distance between the fingers (m); `gripper_command`: the last gripper command,
      `GRIPPER_OPEN` or `GRIPPER_CLOSE`, given at `gripper_since` (s).
    - `contacts`: every (arm link, model) pair in contact now; `Contact.finger` marks the gripper's fingers.
      Contacts with the ground carry `GROUND`. `self_contacts`: pairs of the arm's own links touching.
    - `target`: the model to pick (None: the scenario names none), `target_held`: both fingers touch it.
    - `objects`: the poses now of the target, the table and the scenario's `watch` models; `start_objects`:
      their poses at the start.
    - `place`: the centre of the place region (z may be None), `place_tolerance`: its radius (m, planar).
    - `table`: the table model (None: none named), `table_top`: the z of its top surface (None: unknown).
    """

    time: float
    timeout: float
    pose: Pose6
    history: History
    joint_names: tuple[str, ...]
    joint_positions: tuple[float, ...]
    joint_velocities: tuple[float, ...]
    joint_lower: tuple[float, ...]
    joint_upper: tuple[float, ...]
    gripper_opening: float
    gripper_command: str
    gripper_since: float
    contacts: tuple[Contact, ...]
    self_contacts: tuple[tuple[str, str], ...]
    target: str | None
    target_held: bool
    objects: Mapping[str, Pose6]
    start_objects: Mapping[str, Pose6]
    place: tuple[float, float, float | None]
    place_tolerance: float
    table: str | None
    table_top: float | None

    @property
    def position(self) -> tuple[float, float, float]:
        """The end effector's position."""
        return self.pose[0], self.pose[1], self.pose[2]

    @property
    def touched(self) -> tuple[str, ...]:
        """Models (not the ground) in contact with any arm link now, sorted."""
        return tuple(sorted({c.model for c in self.contacts if c.model != GROUND}))

    @property
    def target_pose(self) -> Pose6 | None:
        """The target's pose now (None: no target)."""
        return None if self.target is None else self.objects.get(self.target)

    def place_distance(self, model: str) -> float:
        """Planar distance (m) from `model`'s position now to the centre of the place region."""
        x, y = self.objects[model][:2]
        return math.hypot(x - self.place[0], y - self.place[1])

    @staticmethod
    def tilt(pose: Pose6) -> float:
        """Angle between a body's up axis and the world's up axis (radians)."""
        return math.acos(max(-1.0, min(1.0, math.cos(pose[3]) * math.cos(pose[4]))))
