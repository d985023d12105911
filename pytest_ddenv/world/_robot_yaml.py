"""The mapping form of `scenario.robot` in a world file: a wheeled robot, or an arm (`arm_joints`), described
by its URDF.

Parsed strictly (every error names the file and the field, e.g. `scenario.robot.left_wheels`) and written
back in the same form. No pybullet here: the URDF is only checked to exist; the simulation reads it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

from pytest_ddenv.validation import is_flag
from pytest_ddenv.world.files import regular_file_problem, resolve_relative
from pytest_ddenv.world.model import DRIVE_KINDS, ArmDescription, LaserMount, RobotDescription

ROBOT_KEYS = (
    "urdf", "drive", "left_wheels", "right_wheels", "wheel_radius", "track", "track_factor", "max_wheel_torque",
    "laser", "name",
)
ARM_KEYS = ("urdf", "arm_joints", "finger_joints", "end_effector", "home", "mjcf", "name")
"""The keys of an arm's mapping (told from a wheeled robot's by `arm_joints`)."""
LASER_KEYS = ("height", "min_range", "x", "y", "yaw")
"""The keys of a `laser` mapping: height and min_range are required, the mounting's x, y and yaw optional."""
FIELD = "scenario.robot"


class FieldReader(Protocol):
    """What the parser needs from the YAML reader (yaml_format._Reader)."""

    source: str | None

    def fail(self, field: str | None, message: str) -> Exception: ...

    def mapping(self, value: Any, field: str, allowed: tuple[str, ...]) -> Mapping[str, Any]: ...

    def number(self, value: Any, field: str, *, positive: bool = False, non_negative: bool = False) -> float: ...

    def text(self, value: Any, field: str) -> str: ...


def parse_robot(reader: FieldReader, value: Any) -> str | RobotDescription | ArmDescription:
    """A registered robot's name, or a `RobotDescription` from a mapping (an `ArmDescription` from a mapping
    with `arm_joints`)."""
    if not isinstance(value, Mapping):
        return reader.text(value, FIELD)
    if "arm_joints" in value:
        return _parse_arm(reader, value)
    data = reader.mapping(value, FIELD, ROBOT_KEYS)
    for key in ("urdf", "left_wheels", "right_wheels"):
        if key not in data:
            raise reader.fail(f"{FIELD}.{key}", "missing; a robot mapping needs urdf, left_wheels and right_wheels")
    urdf = reader.text(data["urdf"], f"{FIELD}.urdf")
    resolved = resolve_relative(urdf, reader.source)
    problem = regular_file_problem(resolved, "URDF file")
    if problem is not None:
        raise reader.fail(f"{FIELD}.urdf", problem)
    drive = data.get("drive", "differential")
    if drive not in DRIVE_KINDS:
        raise reader.fail(f"{FIELD}.drive", f"expected one of {', '.join(DRIVE_KINDS)}, got {drive!r}")

    def optional(key: str) -> float | None:
        return None if data.get(key) is None else reader.number(data[key], f"{FIELD}.{key}", positive=True)

    left = _joint_names(reader, data["left_wheels"], f"{FIELD}.left_wheels")
    right = _joint_names(reader, data["right_wheels"], f"{FIELD}.right_wheels")
    both = [name for name in right if name in left]
    if both:
        raise reader.fail(f"{FIELD}.right_wheels", f"{', '.join(map(repr, both))} is also in left_wheels; a wheel "
                                                   "joint drives one side")
    return RobotDescription(
        urdf=urdf,
        left_wheels=left,
        right_wheels=right,
        drive=drive,
        wheel_radius=optional("wheel_radius"),
        track=optional("track"),
        track_factor=optional("track_factor"),
        max_wheel_torque=reader.number(data.get("max_wheel_torque", 20.0), f"{FIELD}.max_wheel_torque",
                                       positive=True),
        laser=_laser(reader, data.get("laser", True)),
        name=reader.text(data["name"], f"{FIELD}.name") if "name" in data else "",
    )


def _parse_arm(reader: FieldReader, value: Mapping[str, Any]) -> ArmDescription:
    data = reader.mapping(value, FIELD, ARM_KEYS)
    for key in ("urdf", "finger_joints", "end_effector"):
        if key not in data:
            raise reader.fail(f"{FIELD}.{key}", "missing; an arm's mapping needs urdf, arm_joints, finger_joints and "
                                                "end_effector")
    files = {}
    for key in ("urdf", "mjcf"):
        if key in data:
            files[key] = reader.text(data[key], f"{FIELD}.{key}")
            problem = regular_file_problem(resolve_relative(files[key], reader.source), f"{key.upper()} file")
            if problem is not None:
                raise reader.fail(f"{FIELD}.{key}", problem)
    arm = _joint_names(reader, data["arm_joints"], f"{FIELD}.arm_joints")
    fingers = _joint_names(reader, data["finger_joints"], f"{FIELD}.finger_joints")
    home = None
    if data.get("home") is not None:
        raw = data["home"]
        if not isinstance(raw, list) or len(raw) != len(arm):
            raise reader.fail(f"{FIELD}.home", f"expected a list of {len(arm)} joint positions (one per arm joint), "
                                               f"got {raw!r}")
        home = tuple(reader.number(v, f"{FIELD}.home[{i}]") for i, v in enumerate(raw))
    return ArmDescription(
        urdf=files["urdf"], arm_joints=arm, finger_joints=fingers,
        end_effector=reader.text(data["end_effector"], f"{FIELD}.end_effector"), home=home,
        mjcf=files.get("mjcf"), name=reader.text(data["name"], f"{FIELD}.name") if "name" in data else "",
    )


def _joint_names(reader: FieldReader, value: Any, field: str) -> tuple[str, ...]:
    names = [value] if isinstance(value, str) else value
    if not isinstance(names, list) or not names:
        raise reader.fail(field, f"expected a joint name or a non-empty list of joint names, got {value!r}")
    return tuple(reader.text(name, f"{field}[{index}]") for index, name in enumerate(names))


def _laser(reader: FieldReader, value: Any) -> bool | LaserMount:
    if is_flag(value):
        return value
    if not isinstance(value, Mapping):
        raise reader.fail(f"{FIELD}.laser", f"expected true, false or a mapping {{height, min_range[, x, y, yaw]}}, "
                                            f"got {value!r}")
    data = reader.mapping(value, f"{FIELD}.laser", LASER_KEYS)
    for key in ("height", "min_range"):
        if key not in data:
            raise reader.fail(f"{FIELD}.laser.{key}", "missing; give both height and min_range (m), or true/false")
    return LaserMount(
        height=reader.number(data["height"], f"{FIELD}.laser.height"),
        min_range=reader.number(data["min_range"], f"{FIELD}.laser.min_range", non_negative=True),
        **{key: reader.number(data[key], f"{FIELD}.laser.{key}") for key in ("x", "y", "yaw") if key in data},
    )


def robot_dict(robot: str | RobotDescription | ArmDescription, source: str | None, relative_to: Path | None) -> Any:
    """`scenario.robot` as written to a world file (paths rebased onto `relative_to` when given)."""
    if isinstance(robot, str):
        return robot
    if isinstance(robot, ArmDescription):
        arm: dict[str, Any] = {"urdf": rebased(robot.urdf, source, relative_to), "arm_joints": list(robot.arm_joints),
                               "finger_joints": list(robot.finger_joints), "end_effector": robot.end_effector}
        if robot.home is not None:
            arm["home"] = list(robot.home)
        if robot.mjcf is not None:
            arm["mjcf"] = rebased(robot.mjcf, source, relative_to)
        if robot.name:
            arm["name"] = robot.name
        return arm
    data: dict[str, Any] = {"urdf": rebased(robot.urdf, source, relative_to), "drive": robot.drive,
                            "left_wheels": list(robot.left_wheels), "right_wheels": list(robot.right_wheels)}
    for key in ("wheel_radius", "track", "track_factor"):
        if getattr(robot, key) is not None:
            data[key] = getattr(robot, key)
    data["max_wheel_torque"] = robot.max_wheel_torque
    if isinstance(robot.laser, LaserMount):
        mount = robot.laser
        data["laser"] = {"height": mount.height, "min_range": mount.min_range,
                         **{key: getattr(mount, key) for key in ("x", "y", "yaw") if getattr(mount, key)}}
    elif robot.laser is False:
        data["laser"] = False
    if robot.name:
        data["name"] = robot.name
    return data


def rebased(file: str, source: str | None, relative_to: Path | None) -> str:
    """A relative file path of a world read from `source`, made relative to the folder `relative_to`
    (where the world is being written) so that the written file still finds it."""
    if relative_to is None or source is None or Path(file).expanduser().is_absolute():
        return file
    target = resolve_relative(file, source).resolve()
    return os.path.relpath(target, Path(relative_to).resolve())
