"""The pluggable robot interface, wheeled robots from a URDF, and the built-in Clearpath Husky.

A robot knows how to spawn itself in a pybullet client, which of its links are wheels, how to turn a
command into motor commands, and what its wheel encoders measure. The simulator supplies everything else:
noise, localisation (dead reckoning plus a noisy IMU yaw), sensing, the controller and the predicates.

Most wheeled robots need no Python: `WheeledRobot` (or the `scenario.robot` mapping of a world file) reads
wheel radius, track, footprint and mass from the URDF. For anything else subclass `Robot` and register it
with `register_robot("name", factory)`.
"""

from __future__ import annotations

import abc
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from pytest_ddenv.errors import ControllerError, ScenarioError
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.sim.urdf_geometry import (
    UrdfGeometry,
    check_wheel_joints,
    measure_urdf,
    pybullet_installed,
    urdf_joint_names,
)
from pytest_ddenv.validation import expected
from pytest_ddenv.world.files import regular_file_problem, resolve_relative
from pytest_ddenv.world.model import DRIVE_KINDS, ArmDescription, LaserMount, RobotDescription

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""


class Robot(abc.ABC):
    """A mobile robot driven by (linear, angular) commands. One instance serves one run. (An arm is a `Robot`
    too, sim/arm/robot.py's `ArmRobot`: the engine that spawns it gives it an `arm` for an arm's commands.)

    Geometry attributes (metres, robot frame: x forward, y left): `footprint` (length, width), used to find
    the support under the start pose and drawn in pictures; `base_height`, how far above the support surface
    the base frame is spawned; `laser` (a `LaserMount`, or None for a robot without a laser).
    """

    name: str = "robot"
    footprint: tuple[float, float] = (1.0, 0.6)
    base_height: float = 0.0
    laser_height: float = 0.3
    laser_min_range: float = 0.6
    laser_x: float = 0.0
    laser_y: float = 0.0
    laser_yaw: float = 0.0
    has_laser: bool = True

    @property
    def laser(self) -> LaserMount | None:
        """Where the laser sits (from `laser_height`, `laser_min_range` and its place on the robot, `laser_x`,
        `laser_y`, `laser_yaw`), or None: no laser."""
        if not self.has_laser:
            return None
        return LaserMount(self.laser_height, self.laser_min_range, self.laser_x, self.laser_y, self.laser_yaw)

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

    def drive_wheels(self, left: float, right: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        """Command each side's wheel speed (rad/s). Robots that cannot say no here (the default)."""
        raise ControllerError(f"the robot {self.name!r} takes Command(linear, angular) only, not WheelCommand")

    def odometry(self) -> tuple[tuple[float, ...], float, float]:
        """(wheel speeds in rad/s, linear, angular) from one reading of the wheel encoders."""
        linear, angular = self.measured_velocity()
        return (), linear, angular


class WheeledRobot(Robot):
    """A differential-drive or skid-steer robot from a URDF, driven by wheel velocity motors.

    `left_wheels` / `right_wheels` name the wheel joints. `wheel_radius`, `track` (left-right wheel
    distance), the footprint, the base height and the mass are read from the URDF unless given. Kinematics:
    `left/right = (linear -/+ angular * track * track_factor / 2) / wheel_radius` rad/s, with `track_factor`
    1 for a differential drive and 1.5 for skid steering (its wheels slip sideways in turns; bullet3's
    Husky example uses 1.5). `laser`: True mounts a laser on top of the robot, False none, or a
    `LaserMount`. The URDF is loaded with implicit wheel cylinders and merged fixed links (faster).
    """

    # Over 60 lines by its signature alone: one keyword per entry of a world file's robot mapping.
    def __init__(
        self,
        urdf: str | os.PathLike[str],
        *,
        left_wheels: Sequence[str],
        right_wheels: Sequence[str],
        drive: str = "differential",
        wheel_radius: float | None = None,
        track: float | None = None,
        track_factor: float | None = None,
        max_wheel_torque: float = 20.0,
        laser: bool | LaserMount = True,
        name: str = "",
        implicit_cylinder: bool = True,
        merge_fixed_links: bool = True,
        footprint: tuple[float, float] | None = None,
        base_height: float | None = None,
        mass: float | None = None,
        wheel_order: Sequence[str] | None = None,
        source: str | None = None,
    ) -> None:
        self.urdf = str(urdf)
        self.source = source
        problem = regular_file_problem(Path(self.urdf), "URDF file")  # pybullet would wait forever on a FIFO
        if problem is not None:
            raise ScenarioError(problem, source=source, field="scenario.robot.urdf")
        self.left, self.right = tuple(left_wheels), tuple(right_wheels)
        if not self.left or not self.right:
            raise ScenarioError("a wheeled robot needs at least one left and one right wheel joint",
                                source=source, field="scenario.robot.left_wheels" if not self.left
                                else "scenario.robot.right_wheels")
        if drive not in DRIVE_KINDS:
            raise ScenarioError(f"unknown drive {drive!r}; expected one of {', '.join(DRIVE_KINDS)}",
                                source=source, field="scenario.robot.drive")
        self.wheel_names = tuple(wheel_order) if wheel_order is not None else self.left + self.right
        self.name = name or os.path.splitext(os.path.basename(self.urdf))[0]
        self.drive_kind = drive
        self.max_force = float(max_wheel_torque)
        self.implicit_cylinder = implicit_cylinder
        self.merge_fixed_links = merge_fixed_links
        measured: UrdfGeometry | None = None
        if None in (wheel_radius, track, footprint, base_height) or laser is True:  # it checks the joints too
            measured = measure_urdf(self.urdf, self._flags(), self.left, self.right, source=source)
        else:  # found now, before a run spawns the robot
            check_wheel_joints(self.urdf, urdf_joint_names(self.urdf, self._flags(), source=source), self.left,
                               self.right, source=source)
        self.wheel_radius = float(wheel_radius if wheel_radius is not None else measured.wheel_radius)  # type: ignore[union-attr]
        if track is None and measured.track is None:  # type: ignore[union-attr]
            raise ScenarioError(f"{self.urdf}: the left and right wheels are at the same lateral position, so the "
                                "track cannot be read; give track", source=source, field="scenario.robot.track")
        self.track = float(track if track is not None else measured.track)  # type: ignore[union-attr, arg-type]
        self.track_factor = float(track_factor if track_factor is not None else
                                  (1.5 if drive == "skid-steer" else 1.0))
        self.footprint = footprint if footprint is not None else measured.footprint  # type: ignore[union-attr]
        self.base_height = float(base_height if base_height is not None else measured.base_height)  # type: ignore[union-attr]
        mount = laser if isinstance(laser, LaserMount) else (measured.laser if laser and measured else None)
        self.has_laser = mount is not None
        if mount is not None:
            self.laser_height, self.laser_min_range = mount.height, mount.min_range
            self.laser_x, self.laser_y, self.laser_yaw = mount.x, mount.y, mount.yaw
        self._known_mass = mass
        self.wheel_motors: Callable[[float, float], None] | None = None
        """Where the (left, right) wheel speeds go when not to pybullet's motors: another engine's (MuJoCo's
        robot sets it, so that a subclass's `drive` and `drive_wheels` are its commands in every engine)."""
        self._client = -1
        self._body = -1
        self._wheels: tuple[int, ...] = ()
        self._sides: tuple[bool, ...] = tuple(wheel in self.left for wheel in self.wheel_names)
        self._links: dict[int, str] = {}
        self._mass = 0.0

    @classmethod
    def from_description(cls, description: RobotDescription, source: str | None = None) -> WheeledRobot:
        """The robot a world file's `scenario.robot` mapping describes (`source`: the world file)."""
        return cls(
            resolve_relative(description.urdf, source), left_wheels=description.left_wheels,
            right_wheels=description.right_wheels, drive=description.drive,
            wheel_radius=description.wheel_radius, track=description.track, track_factor=description.track_factor,
            max_wheel_torque=description.max_wheel_torque, laser=description.laser, name=description.label,
            source=source,
        )

    def _flags(self) -> int:
        if not pybullet_installed():  # MuJoCo reads the URDF itself
            return 0
        with silenced():  # importing pybullet prints its build time on the C-level stdout
            import pybullet as p

        flags = p.URDF_USE_IMPLICIT_CYLINDER if self.implicit_cylinder else 0
        if self.merge_fixed_links:
            flags |= p.URDF_MERGE_FIXED_LINKS
        return int(flags)

    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        import pybullet as p

        with silenced():
            body = p.loadURDF(self.urdf, list(position), p.getQuaternionFromEuler([0.0, 0.0, yaw]),
                              flags=self._flags(), physicsClientId=client)
        self._client, self._body = client, body
        joints: dict[str, int] = {}
        self._links = {-1: p.getBodyInfo(body, physicsClientId=client)[0].decode()}
        mass = p.getDynamicsInfo(body, -1, physicsClientId=client)[0]
        for index in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, index, physicsClientId=client)
            joints[info[1].decode()] = index
            self._links[index] = info[12].decode()
            mass += p.getDynamicsInfo(body, index, physicsClientId=client)[0]
        check_wheel_joints(self.urdf, joints, self.left, self.right, source=self.source)
        self._wheels = tuple(joints[name] for name in self.wheel_names)
        self._mass = mass if self._known_mass is None else self._known_mass
        # free the wheels from the default velocity motors before commanding them
        count = len(self._wheels)
        p.setJointMotorControlArray(body, list(self._wheels), p.VELOCITY_CONTROL, targetVelocities=[0.0] * count,
                                    forces=[self.max_force] * count, physicsClientId=client)
        return int(body)

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
        self._set_wheel_speeds(*self.side_speeds(linear, angular, scale_left, scale_right))

    def side_speeds(self, linear: float, angular: float, scale_left: float = 1.0,
                    scale_right: float = 1.0) -> tuple[float, float]:
        """The (left, right) wheel speeds in rad/s for a body velocity (the skid-steer kinematics)."""
        half = angular * self.track * self.track_factor / 2.0
        left = (linear - half) / self.wheel_radius * scale_left
        right = (linear + half) / self.wheel_radius * scale_right
        return left, right

    def drive_wheels(self, left: float, right: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        self._set_wheel_speeds(float(left) * scale_left, float(right) * scale_right)

    def _set_wheel_speeds(self, left: float, right: float) -> None:
        if self.wheel_motors is not None:
            self.wheel_motors(left, right)
            return
        import pybullet as p

        targets = [left if is_left else right for is_left in self._sides]
        p.setJointMotorControlArray(self._body, list(self._wheels), p.VELOCITY_CONTROL, targetVelocities=targets,
                                    forces=[self.max_force] * len(targets), physicsClientId=self._client)

    def odometry(self) -> tuple[tuple[float, ...], float, float]:
        import pybullet as p

        states = p.getJointStates(self._body, list(self._wheels), physicsClientId=self._client)
        return self.odometry_of(tuple(float(state[1]) for state in states))

    def odometry_of(self, speeds: tuple[float, ...]) -> tuple[tuple[float, ...], float, float]:
        """(speeds, linear, angular) that the wheel speeds `speeds` (rad/s, the robot's wheel order) imply."""
        left_speeds = [s for s, is_left in zip(speeds, self._sides, strict=True) if is_left]
        right_speeds = [s for s, is_left in zip(speeds, self._sides, strict=True) if not is_left]
        left = sum(left_speeds, 0.0) / len(left_speeds) * self.wheel_radius
        right = sum(right_speeds, 0.0) / len(right_speeds) * self.wheel_radius
        return speeds, (left + right) / 2.0, (right - left) / (self.track * self.track_factor)

    def measured_velocity(self) -> tuple[float, float]:
        _, linear, angular = self.odometry()
        return linear, angular


class Husky(WheeledRobot):
    """The Clearpath Husky from `pybullet_data` (`husky/husky.urdf`), skid-steered by wheel velocity.

    Skid steering uses an effective track 1.5 x the real 0.5708 m and 100 N m per wheel, as in bullet3's
    examples (measured facts in docs/simulation.md). With implicit wheel cylinders and merged fixed links
    (about 1.5x faster), the base frame is the merged chassis's centre of mass, about 0.17 m above the
    ground when level; the URDF root (base_footprint) is at the wheel contact plane.
    """

    WHEELS = ("front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel")

    def __init__(self, urdf: str | None = None, *, implicit_cylinder: bool = True,
                 merge_fixed_links: bool = True) -> None:
        if urdf is None:
            urdf = husky_urdf()
        super().__init__(
            urdf, left_wheels=("front_left_wheel", "rear_left_wheel"),
            right_wheels=("front_right_wheel", "rear_right_wheel"), drive="skid-steer", wheel_radius=0.17775,
            track=0.5708, track_factor=1.5, max_wheel_torque=100.0, laser=LaserMount(0.35, 0.62), name="husky",
            implicit_cylinder=implicit_cylinder, merge_fixed_links=merge_fixed_links, footprint=(0.99, 0.67),
            base_height=0.0, wheel_order=self.WHEELS,
        )


def husky_urdf() -> str:
    """pybullet_data's husky/husky.urdf, or without pybullet the copy shipped in this package (the same file,
    BSD licence of Clearpath Robotics in its header; its STL meshes are visual only and not shipped)."""
    try:
        import pybullet_data
    except ImportError:
        return str(Path(__file__).parent / "husky" / "husky.urdf")
    return os.path.join(pybullet_data.getDataPath(), "husky", "husky.urdf")


RobotFactory = Callable[[], Robot]
ROBOTS: dict[str, RobotFactory] = {"husky": Husky}
"""Registered robots by the name a world file's `scenario.robot` uses (sim/arm/robot.py adds "panda")."""
ArmFactory = Callable[[ArmDescription, "str | None"], Robot]
_arm_factory: list[ArmFactory] = []


def register_arm_factory(factory: ArmFactory) -> None:
    """How an `ArmDescription` becomes a robot: sim/arm/robot.py's `ArmRobot`, registered when that module is
    imported (sim/__init__.py imports it: this module cannot, the arm's robot is a `Robot`)."""
    _arm_factory[:] = [factory]


def register_robot(name: str, robot: RobotFactory | RobotDescription, *, replace: bool = False) -> None:
    """Make a robot available as `robot: name` in world files: a factory returning a `Robot`, or a
    `RobotDescription` (its relative URDF path is taken from the current working directory).

    Registrations made in a test module, a conftest or a module the test imports reach every probe
    worker: workers import them as pytest does.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(expected("a non-empty string", name, "register_robot(name=...)"))
    if name in ROBOTS and not replace:
        raise ValueError(f"a robot named {name!r} is already registered (pass replace=True)")
    if isinstance(robot, RobotDescription):
        caller = sys._getframe(1)
        where = f"{Path(caller.f_code.co_filename).name}:{caller.f_lineno}"
        urdf = Path(robot.urdf).expanduser()
        if not urdf.is_file():
            raise ValueError(f"register_robot({name!r}, ...) at {where}: URDF file not found: {robot.urdf} (a "
                             f"relative path is taken from the current folder, {Path.cwd()})")
        ROBOTS[name] = partial(_described, name, where, robot)
    elif callable(robot):
        ROBOTS[name] = robot
    else:
        raise TypeError(expected("a factory returning a Robot or a RobotDescription", robot,
                                 f"register_robot({name!r}, ...)"))


def _described(name: str, where: str, description: RobotDescription) -> WheeledRobot:
    """The robot registered as `name` (at `where`) by its description; its errors name it."""
    try:
        return WheeledRobot.from_description(description)
    except ScenarioError as error:
        raise ScenarioError(f"robot {name!r} (registered at {where}): {error.reason}", field=error.field) from None


def check_robot(robot: str | RobotDescription | ArmDescription, source: str | None = None) -> None:
    """Build a scenario's robot as a run does, without a simulation, when it is described by its URDF (a world
    file's `scenario.robot` mapping, or a name registered with a `RobotDescription`): a URDF pybullet cannot
    load, a wheel joint it does not have, an arm's joint or end-effector link it does not have, a wheel without
    a collision shape raise `ScenarioError` naming the
    world file `source` and the field. A robot of a factory of yours, or a name not registered (yet), is left
    to the run."""
    factory = ROBOTS.get(robot) if isinstance(robot, str) else None
    described = isinstance(factory, partial) and factory.func is _described
    if isinstance(robot, (RobotDescription, ArmDescription)) or described:
        make_robot(robot, source)


def make_robot(robot: str | RobotDescription | ArmDescription, source: str | None = None) -> Robot:
    """The robot of a scenario: a registered name or a description (`source`: the world file)."""
    if isinstance(robot, ArmDescription):
        return _arm_factory[0](robot, source)
    if isinstance(robot, RobotDescription):
        return WheeledRobot.from_description(robot, source)
    try:
        factory = ROBOTS[robot]
    except KeyError:
        raise ScenarioError(f"unknown robot {robot!r}; registered robots: {', '.join(sorted(ROBOTS))}",
                            source=source, field="scenario.robot") from None
    made: Any = factory()
    if not isinstance(made, Robot):
        raise ScenarioError(f"the factory registered as robot {robot!r} returned {type(made).__name__}, not a "
                            "Robot", source=source, field="scenario.robot")
    return made
