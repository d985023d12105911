"""The controller interface: what a controller sees each control tick (`Observation`) and what it returns
(`Command`, or `WheelCommand` for direct wheel speeds).

A controller is any callable `controller(observation) -> command`: a plain function, or an object with
`__call__` and, optionally, `reset(observation)` (called once per run, before the first call, with the
first observation). It is the system under test: what it raises fails the run like any exception of the
test, and what it returns is checked (`check_command`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.errors import ControllerError
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.validation import expected, is_real

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import Contact

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One sweep of the robot's planar laser. `angles` are in the robot's frame (0 is straight ahead,
    counterclockwise; a laser mounted turned has its `yaw` added), `ranges` are measured from the laser,
    which sits at `origin` (x forward, y left of the robot's base, m; (0, 0) unless its mounting says).

    `ranges` (m, with the seeded sensing noise) are `inf` where a ray hit nothing but the ground within
    `max_range`. Both arrays are read-only. `time` is when the sweep was taken (the laser runs slower than
    the controller, so consecutive observations may share a scan).
    """

    ranges: FloatArray
    angles: FloatArray
    max_range: float
    time: float
    origin: tuple[float, float] = (0.0, 0.0)

    def points(self) -> FloatArray:
        """(K, 2) x, y of the finite hits in the robot frame."""
        finite = np.isfinite(self.ranges)
        return np.stack([self.origin[0] + self.ranges[finite] * np.cos(self.angles[finite]),
                         self.origin[1] + self.ranges[finite] * np.sin(self.angles[finite])], axis=1)


@dataclass(frozen=True, eq=False)
class Observation:
    """What the robot knows at one control tick, as its own sensors report it (world frame, SI units).

    - `time`: simulated seconds since the robot was spawned; `goal`: the goal (x, y, z or None).
    - `pose`: the robot's own estimate (x, y, yaw): x and y by dead reckoning from the wheel encoders (wrong
      when wheels slip), yaw from the IMU, both with the seeded noise. Not the true pose.
    - `velocity`: (linear m/s, angular rad/s) as the wheel encoders imply (with odometry noise).
    - `wheel_speeds`: each wheel's measured speed (rad/s), in the robot's wheel order.
    - `imu`: (roll, pitch, yaw) in radians; yaw with the IMU noise.
    - `scan`: the latest laser scan, or None when the robot has no laser.
    - `contacts`: what the robot touches now (bumper-like: model names and normal forces).
    """

    time: float
    goal: tuple[float, float, float | None]
    pose: tuple[float, float, float]
    velocity: tuple[float, float]
    wheel_speeds: tuple[float, ...]
    imu: tuple[float, float, float]
    scan: LaserScan | None
    contacts: tuple[Contact, ...]

    @property
    def goal_offset(self) -> tuple[float, float]:
        """(dx, dy) from the estimated position to the goal, world frame."""
        return self.goal[0] - self.pose[0], self.goal[1] - self.pose[1]

    @property
    def goal_distance(self) -> float:
        """Planar distance from the estimated position to the goal."""
        return math.hypot(*self.goal_offset)

    @property
    def goal_bearing(self) -> float:
        """Angle of the goal relative to the estimated heading, in (-pi, pi] (positive: to the left)."""
        dx, dy = self.goal_offset
        return wrap_angle(math.atan2(dy, dx) - self.pose[2])


@dataclass(frozen=True)
class Command:
    """A body velocity for a mobile base: `linear` (m/s, forward) and `angular` (rad/s, counterclockwise).
    The robot maps it to its wheels (differential or skid-steer kinematics)."""

    linear: float = 0.0
    angular: float = 0.0


@dataclass(frozen=True)
class WheelCommand:
    """Direct wheel speeds (rad/s) for the left and right side of a wheeled robot."""

    left: float
    right: float


AnyCommand = Command | WheelCommand


@runtime_checkable
class Controller(Protocol):
    """`controller(observation) -> Command | WheelCommand`; an optional `reset(observation)` is called once
    per run with the first observation."""

    def __call__(self, observation: Observation) -> AnyCommand: ...


ControllerLike = Controller | Callable[[Observation], AnyCommand]


def wrap_angle(angle: float) -> float:
    """`angle` wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def controller_name(controller: object) -> str:
    """How errors name a controller: its function or class name."""
    name = getattr(controller, "__qualname__", None) or type(controller).__qualname__
    return str(name)


def check_controller(controller: object, where: str = "controller") -> None:
    """Raise TypeError unless `controller` can be called with an observation."""
    if not callable(controller):
        raise TypeError(expected("a callable controller(observation) -> Command", controller, where))
    reset = getattr(controller, "reset", None)
    if reset is not None and not callable(reset):
        raise TypeError(expected("a method reset(observation)", reset, f"{where}.reset"))


def check_command(value: Any, controller: object, time: float) -> AnyCommand:
    """The command a controller returned, or ControllerError saying what was wrong and when."""
    if not isinstance(value, (Command, WheelCommand)):
        raise ControllerError(
            f"controller {controller_name(controller)} returned {type(value).__name__} {value!r} at "
            f"t = {time:.2f} s; expected Command(linear=..., angular=...) or WheelCommand(left=..., right=...)"
        )
    numbers = (value.linear, value.angular) if isinstance(value, Command) else (value.left, value.right)
    for number in numbers:
        if not is_real(number) or not math.isfinite(float(number)):
            raise ControllerError(
                expected("finite speeds", value, f"controller {controller_name(controller)} at t = {time:.2f} s")
            )
    return value
