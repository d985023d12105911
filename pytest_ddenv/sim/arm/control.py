"""An arm's controller interface: what it sees each control tick (`ArmObservation`) and what it returns.

A controller is any callable `controller(observation) -> command`, as for mobile robots (sim/control.py),
with an optional `reset(observation)`. The commands: `JointTargets` (a position for every arm joint),
`EndEffectorTarget` (a tool position and yaw, pointing down; inverse kinematics turns it into joint targets)
and `GripperCommand` (open or close, alone). The first two also carry an optional gripper command.
`check_arm_command` checks what a controller returned.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.errors import ControllerError
from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, GRIPPER_OPEN, Pose6
from pytest_ddenv.oracle.predicates import Contact
from pytest_ddenv.sim.control import controller_name
from pytest_ddenv.validation import expected, is_real

GRIPPER_ACTIONS = (GRIPPER_OPEN, GRIPPER_CLOSE)


@dataclass(frozen=True, eq=False)
class ArmObservation:
    """What an arm's controller knows at one control tick (world frame, SI units).

    - `time`: simulated seconds since the start.
    - `joint_positions`, `joint_velocities`: the arm joints' (with the seeded sensing noise), in `joint_names`
      order.
    - `end_effector`: the tool's pose (x, y, z, roll, pitch, yaw): the forward kinematics of the joints'
      true positions (the arm's own kinematics knows them better than the noisy readings say).
    - `gripper_opening`: the distance between the fingers (m); `gripper_force`: the summed normal force the
      fingers feel (N).
    - `contacts`: what the arm touches now (model names, links, normal forces; `finger` marks the fingers).
    - `objects`: the poses of the target, the table and the scenario's `watch` models (as a perception system
      would report them); `target`: the target's name (None: none).
    - `place`: the centre of the place region (z None: on the table), `place_tolerance`: its radius.
    - `image`: the declared camera's picture ((H, W, 3) uint8 RGB, or (H, W) float32 depth in m), or None.
    """

    time: float
    joint_names: tuple[str, ...]
    joint_positions: tuple[float, ...]
    joint_velocities: tuple[float, ...]
    end_effector: Pose6
    gripper_opening: float
    gripper_force: float
    contacts: tuple[Contact, ...]
    objects: Mapping[str, Pose6]
    target: str | None
    place: tuple[float, float, float | None]
    place_tolerance: float
    image: NDArray[np.generic] | None = None

    @property
    def target_pose(self) -> Pose6 | None:
        """The target's pose (None: no target)."""
        return None if self.target is None else self.objects.get(self.target)


@dataclass(frozen=True)
class JointTargets:
    """A position target for every arm joint (rad or m, clipped to the URDF's limits), reached by the
    joints' position controllers within their velocity and effort limits; `gripper`: "open", "close" or None
    (unchanged)."""

    positions: tuple[float, ...]
    gripper: str | None = None


@dataclass(frozen=True)
class EndEffectorTarget:
    """A tool position (x, y, z, m) with the gripper pointing down, turned by `yaw` (rad) about the vertical;
    inverse kinematics turns it into joint targets. `gripper`: "open", "close" or None (unchanged)."""

    position: tuple[float, float, float]
    yaw: float = 0.0
    gripper: str | None = None


@dataclass(frozen=True)
class GripperCommand:
    """Open or close the gripper ("open" / "close"), the arm holding its joint targets."""

    action: str


ArmCommand = JointTargets | EndEffectorTarget | GripperCommand
ArmController = Callable[[ArmObservation], ArmCommand]
"""An arm's controller: `controller(observation) -> command`, optionally with `reset(observation)`."""


def check_arm_command(value: Any, controller: object, time: float, joints: int | None = None) -> ArmCommand:
    """The command an arm's controller returned, or ControllerError saying what was wrong and when (`joints`:
    how many positions a `JointTargets` must hold)."""
    where = f"controller {controller_name(controller)} at t = {time:.2f} s"
    if not isinstance(value, (JointTargets, EndEffectorTarget, GripperCommand)):
        raise ControllerError(
            f"{where} returned {type(value).__name__} {value!r}; an arm's controller returns JointTargets(positions), "
            "EndEffectorTarget(position, yaw) or GripperCommand('open' | 'close')"
        )
    if isinstance(value, GripperCommand):
        actions: tuple[object, ...] = (value.action,)
    else:
        actions = () if value.gripper is None else (value.gripper,)
    for action in actions:
        if action not in GRIPPER_ACTIONS:
            raise ControllerError(expected(f"a gripper action {GRIPPER_OPEN!r} or {GRIPPER_CLOSE!r}", action, where))
    numbers: tuple[object, ...] = ()
    if isinstance(value, JointTargets):
        numbers = tuple(value.positions) if isinstance(value.positions, (tuple, list)) else (value.positions,)
    elif isinstance(value, EndEffectorTarget):
        position = value.position if isinstance(value.position, (tuple, list)) else (value.position,)
        if len(position) != 3:
            raise ControllerError(expected("an end-effector position (x, y, z)", value.position, where))
        numbers = (*position, value.yaw)
    for number in numbers:
        if not is_real(number) or not math.isfinite(float(number)):
            raise ControllerError(expected("finite numbers", value, where))
    if isinstance(value, JointTargets) and joints is not None and len(numbers) != joints:
        raise ControllerError(expected(f"JointTargets with {joints} positions (one per arm joint)", value, where))
    return value
