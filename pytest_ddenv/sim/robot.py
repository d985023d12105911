"""The pluggable robot interface and the built-in Clearpath Husky.

A robot knows how to spawn itself in a pybullet client, which of its links are wheels, how to turn a
(linear, angular) velocity command into motor commands, and what its wheel encoders measure. The
simulator supplies everything else: noise, localisation (dead reckoning from `measured_velocity` plus
a noisy IMU yaw), the go-to-goal controller, sensing and the predicates. Register your own robot with
`register_robot("name", factory)` and use `robot: name` in the world file's scenario.
"""

from __future__ import annotations

import abc
import os
from collections.abc import Callable, Mapping
from typing import Any

from pytest_ddenv.sim.quiet import silenced


class Robot(abc.ABC):
    """A mobile robot driven by (v, w) commands. One instance serves one run at a time.

    Geometry attributes (metres, in the robot frame: x forward, y left, z up from the ground contact):
    `footprint` (length, width) used to find the support under the start pose; `laser_height` and
    `laser_min_range` for the 2D laser; `base_height` how far above the support surface the base frame
    sits when the robot rests on it.
    """

    name: str = "robot"
    footprint: tuple[float, float] = (1.0, 0.6)
    base_height: float = 0.0
    laser_height: float = 0.3
    laser_min_range: float = 0.6

    @abc.abstractmethod
    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        """Create the robot in `client` with its base frame at `position`, heading `yaw`; return the body id."""

    @property
    @abc.abstractmethod
    def wheel_links(self) -> tuple[int, ...]:
        """Link indices of the wheels (the rest counts as chassis for contacts)."""

    @property
    @abc.abstractmethod
    def link_names(self) -> Mapping[int, str]:
        """Link index -> name (-1 is the base)."""

    @property
    @abc.abstractmethod
    def mass(self) -> float:
        """Total mass in kg (for the high-centred load fraction)."""

    @abc.abstractmethod
    def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        """Command a body velocity; `scale_*` multiply each side's wheel speed (actuation noise)."""

    @abc.abstractmethod
    def measured_velocity(self) -> tuple[float, float]:
        """The body velocity (linear m/s, angular rad/s) the wheel encoders imply (wrong when wheels slip)."""


class Husky(Robot):
    """The Clearpath Husky from `pybullet_data` (`husky/husky.urdf`), skid-steered by wheel velocity.

    Wheels are looked up by joint name. Skid steering uses an effective track 1.5 x the real 0.5708 m and
    100 N m per wheel, as in bullet3's examples (measured facts in docs/simulation.md). By default the
    URDF is loaded with implicit wheel cylinders and merged fixed links (about 1.5x faster); the base
    frame is then the merged chassis's centre of mass, about 0.17 m above the ground when level.
    """

    name = "husky"
    footprint = (0.99, 0.67)
    base_height = 0.0  # spawn: the URDF root (base_footprint) is at the wheel contact plane
    laser_height = 0.35
    laser_min_range = 0.62
    wheel_radius = 0.17775
    track = 0.5708
    track_factor = 1.5
    max_force = 100.0
    WHEELS = ("front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel")

    def __init__(self, urdf: str | None = None, *, implicit_cylinder: bool = True, merge_fixed_links: bool = True) -> None:
        if urdf is None:
            import pybullet_data

            urdf = os.path.join(pybullet_data.getDataPath(), "husky", "husky.urdf")
        self.urdf = urdf
        self.implicit_cylinder = implicit_cylinder
        self.merge_fixed_links = merge_fixed_links
        self._client = -1
        self._body = -1
        self._wheels: tuple[int, ...] = ()
        self._links: dict[int, str] = {}
        self._mass = 0.0

    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        import pybullet as p

        flags = p.URDF_USE_IMPLICIT_CYLINDER if self.implicit_cylinder else 0
        if self.merge_fixed_links:
            flags |= p.URDF_MERGE_FIXED_LINKS
        with silenced():
            body = p.loadURDF(self.urdf, list(position), p.getQuaternionFromEuler([0.0, 0.0, yaw]),
                              flags=flags, physicsClientId=client)
        self._client, self._body = client, body
        joints: dict[str, int] = {}
        self._links = {-1: p.getBodyInfo(body, physicsClientId=client)[0].decode()}
        mass = p.getDynamicsInfo(body, -1, physicsClientId=client)[0]
        for index in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, index, physicsClientId=client)
            joints[info[1].decode()] = index
            self._links[index] = info[12].decode()
            mass += p.getDynamicsInfo(body, index, physicsClientId=client)[0]
        missing = [name for name in self.WHEELS if name not in joints]
        if missing:
            raise RuntimeError(f"{self.urdf} has no wheel joint(s) {missing}")
        self._wheels = tuple(joints[name] for name in self.WHEELS)
        self._mass = mass
        # free the wheels from the default velocity motors before commanding them
        p.setJointMotorControlArray(body, list(self._wheels), p.VELOCITY_CONTROL, targetVelocities=[0.0] * 4,
                                    forces=[self.max_force] * 4, physicsClientId=client)
        return body

    @property
    def wheel_links(self) -> tuple[int, ...]:
        return self._wheels

    @property
    def link_names(self) -> Mapping[int, str]:
        return self._links

    @property
    def mass(self) -> float:
        return self._mass

    def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        import pybullet as p

        half = angular * self.track * self.track_factor / 2.0
        left = (linear - half) / self.wheel_radius * scale_left
        right = (linear + half) / self.wheel_radius * scale_right
        p.setJointMotorControlArray(self._body, list(self._wheels), p.VELOCITY_CONTROL,
                                    targetVelocities=[left, right, left, right],
                                    forces=[self.max_force] * 4, physicsClientId=self._client)

    def measured_velocity(self) -> tuple[float, float]:
        import pybullet as p

        states = p.getJointStates(self._body, list(self._wheels), physicsClientId=self._client)
        fl, fr, rl, rr = (state[1] for state in states)
        left = (fl + rl) / 2.0 * self.wheel_radius
        right = (fr + rr) / 2.0 * self.wheel_radius
        return (left + right) / 2.0, (right - left) / (self.track * self.track_factor)


RobotFactory = Callable[[], Robot]
ROBOTS: dict[str, RobotFactory] = {"husky": Husky}
"""Registered robots by the name a world file's `scenario.robot` uses."""


def register_robot(name: str, factory: RobotFactory, *, replace: bool = False) -> None:
    """Make `factory()` available as `robot: name` in world files."""
    if not isinstance(name, str) or not name:
        raise ValueError("a robot name must be a non-empty string")
    if name in ROBOTS and not replace:
        raise ValueError(f"a robot named {name!r} is already registered (pass replace=True)")
    ROBOTS[name] = factory


def make_robot(name: str, **_: Any) -> Robot:
    return ROBOTS[name]()
