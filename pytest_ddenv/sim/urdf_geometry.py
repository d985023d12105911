"""What a wheeled robot's URDF says about its geometry: wheel radius, track, footprint, mass, a laser mount.

Measured once per process and URDF in a scratch pybullet client, never in the simulation's own client (a
body loaded and removed there would shift the body ids and, with them, the contact order of later runs); where
pybullet is not installed, compiled and measured by MuJoCo (`urdf_mujoco`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.files import regular_file_problem
from pytest_ddenv.world.model import LaserMount

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

LASER_CLEARANCE = 0.05
"""m: the automatic laser mount sits this far above the robot's top and starts its rays this far outside it."""
_GEOM_SPHERE, _GEOM_CYLINDER, _GEOM_CAPSULE = 2, 4, 7


@dataclass(frozen=True)
class UrdfGeometry:
    """`track` is None when the left and right wheels are at the same lateral position (it cannot be read)."""

    wheel_radius: float
    track: float | None
    footprint: tuple[float, float]
    base_height: float
    mass: float
    laser: LaserMount


_cache: dict[tuple[str, float, int, tuple[str, ...], tuple[str, ...]], UrdfGeometry] = {}
_joints: dict[tuple[str, float, int], tuple[str, ...]] = {}


def urdf_joint_names(urdf: str, flags: int, *, source: str | None = None) -> tuple[str, ...]:
    """The joints of `urdf` loaded with `flags` in a scratch client (cached per file); ScenarioError naming the
    world file `source` when pybullet cannot load it."""
    key = (os.path.abspath(urdf), os.path.getmtime(urdf), flags)
    if key not in _joints and not pybullet_installed():
        _joints[key] = _moving_joints(urdf, source)
    if key not in _joints:
        with silenced():
            import pybullet as p

            client = p.connect(p.DIRECT)
        try:
            body = _load(p, client, urdf, flags, source)
            _joints[key] = tuple(p.getJointInfo(body, j, physicsClientId=client)[1].decode()
                                 for j in range(p.getNumJoints(body, physicsClientId=client)))
        finally:
            p.disconnect(physicsClientId=client)
    return _joints[key]


def pybullet_installed() -> bool:
    """Whether pybullet can be imported (a MuJoCo-only install has no pybullet)."""
    import importlib.util

    return importlib.util.find_spec("pybullet") is not None


def _moving_joints(urdf: str, source: str | None) -> tuple[str, ...]:
    """The URDF's joints that are not fixed, read from its XML (pybullet, merging fixed links, has those)."""
    import defusedxml.ElementTree

    problem = regular_file_problem(Path(urdf), "URDF file")
    if problem is not None:
        raise ScenarioError(problem, source=source, field="scenario.robot.urdf")
    try:
        root = defusedxml.ElementTree.fromstring(Path(urdf).read_bytes())
    except Exception as error:  # noqa: BLE001 - any parse error is the file's
        raise ScenarioError(f"cannot read the URDF {urdf}: {error}", source=source,
                            field="scenario.robot.urdf") from None
    return tuple(str(joint.get("name")) for joint in root.iter("joint") if joint.get("type") != "fixed")


def check_wheel_joints(urdf: str, joints: Collection[str], left: Sequence[str], right: Sequence[str], *,
                       source: str | None = None) -> None:
    """ScenarioError naming the world file `source` and the field (`scenario.robot.left_wheels` or
    `right_wheels`) when a wheel joint is not one of the URDF's `joints`."""
    for side, names in (("left_wheels", left), ("right_wheels", right)):
        missing = [name for name in names if name not in joints]
        if missing:
            raise ScenarioError(f"the robot's URDF {urdf} has no joint named {', '.join(map(repr, missing))}; its "
                                f"joints: {', '.join(sorted(joints)) or '(none)'}", source=source,
                                field=f"scenario.robot.{side}")


def _load(p: Any, client: int, urdf: str, flags: int, source: str | None) -> int:
    """`urdf` loaded at the origin in the scratch `client` (if it is a regular file: pybullet would wait forever
    on a FIFO)."""
    problem = regular_file_problem(Path(urdf), "URDF file")
    if problem is not None:
        raise ScenarioError(problem, source=source, field="scenario.robot.urdf")
    try:
        with silenced():
            return int(p.loadURDF(urdf, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], flags=flags, physicsClientId=client))
    except p.error as error:
        raise ScenarioError(f"pybullet cannot load the URDF {urdf}: {error}", source=source,
                            field="scenario.robot.urdf") from None


def measure_urdf(urdf: str, flags: int, left: Sequence[str], right: Sequence[str], *,
                 source: str | None = None) -> UrdfGeometry:
    """Load `urdf` at the origin (identity pose) in a scratch client and measure it (cached per file)."""
    key = (os.path.abspath(urdf), os.path.getmtime(urdf), flags, tuple(left), tuple(right))
    if key not in _cache:
        _cache[key] = _measure(urdf, flags, tuple(left), tuple(right), source)
    return _cache[key]


def _measure(urdf: str, flags: int, left: tuple[str, ...], right: tuple[str, ...], source: str | None) -> UrdfGeometry:
    if not pybullet_installed():
        return _measure_in_mujoco(urdf, flags, left, right, source)
    with silenced():
        import pybullet as p

        client = p.connect(p.DIRECT)
    try:
        body = _load(p, client, urdf, flags, source)
        joints = {p.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
                  for j in range(p.getNumJoints(body, physicsClientId=client))}
        check_wheel_joints(urdf, joints, left, right, source=source)
        links = [-1, *joints.values()]
        boxes = [p.getAABB(body, link, physicsClientId=client) for link in links]
        low = [min(box[0][axis] for box in boxes) for axis in range(3)]
        high = [max(box[1][axis] for box in boxes) for axis in range(3)]
        radii = [_wheel_radius(p, client, body, joints[name], side, urdf, source)
                 for side, names in (("left_wheels", left), ("right_wheels", right)) for name in names]

        def mean_y(names: tuple[str, ...]) -> float:
            """Lateral position of the wheels' centres (their collision boxes: a wheel's shape may sit off its
            joint along the axle)."""
            centres: list[float] = [sum(p.getAABB(body, joints[n], physicsClientId=client)[k][1] for k in (0, 1)) / 2.0
                                    for n in names]
            return sum(centres) / len(centres)

        mass = sum(p.getDynamicsInfo(body, link, physicsClientId=client)[0] for link in links)
        base, _ = p.getBasePositionAndOrientation(body, physicsClientId=client)
        return _geometry(urdf, low, high, radii, mean_y(left), mean_y(right), mass, base, source)
    finally:
        p.disconnect(physicsClientId=client)


def _measure_in_mujoco(urdf: str, flags: int, left: tuple[str, ...], right: tuple[str, ...],
                       source: str | None) -> UrdfGeometry:
    """Without pybullet: the URDF compiled and measured by MuJoCo (`urdf_mujoco`), its joints checked first."""
    import importlib.util

    if importlib.util.find_spec("mujoco") is None:
        raise ScenarioError(f"the wheel radius, track, footprint, base height and laser mount of {urdf} are measured "
                            "with pybullet or mujoco, and neither is installed: give them in the robot's "
                            'description, or pip install "pytest-ddenv[mujoco]"', source=source,
                            field="scenario.robot")
    from pytest_ddenv.sim.urdf_mujoco import measure_in_mujoco

    check_wheel_joints(urdf, urdf_joint_names(urdf, flags, source=source), left, right, source=source)
    bounds = measure_in_mujoco(urdf, left, right, source=source)
    return _geometry(urdf, list(bounds.low), list(bounds.high), list(bounds.wheel_radii), bounds.left_y,
                     bounds.right_y, bounds.mass, bounds.base, source)


def _geometry(urdf: str, low: Sequence[float], high: Sequence[float], radii: Sequence[float], left_y: float,
              right_y: float, mass: float, base: Sequence[float], source: str | None) -> UrdfGeometry:
    """The robot's geometry from its collision bounds (`low`, `high`), wheel radii, the left and right wheels'
    mean lateral positions, its mass and its base's position, measured at the origin by either engine."""
    if left_y < right_y - 1e-6:
        raise ScenarioError(f"{urdf}: the left wheels are on the robot's right (y = {left_y:.3f} m, the right "
                            f"wheels at y = {right_y:.3f} m; x is forward and y left); swap left_wheels and "
                            "right_wheels", source=source, field="scenario.robot.left_wheels")
    base_x, base_y, base_z = base
    reach = math.hypot(max(abs(low[0] - base_x), abs(high[0] - base_x)),
                       max(abs(low[1] - base_y), abs(high[1] - base_y)))
    return UrdfGeometry(
        wheel_radius=sum(radii) / len(radii),
        track=left_y - right_y if left_y - right_y > 1e-6 else None,
        footprint=(high[0] - low[0], high[1] - low[1]),
        base_height=-low[2],
        mass=mass,
        laser=LaserMount(height=high[2] - base_z + LASER_CLEARANCE, min_range=reach + LASER_CLEARANCE),
    )


def _wheel_radius(p: object, client: int, body: int, joint: int, side: str, urdf: str, source: str | None) -> float:
    """From the wheel link's collision shape: a cylinder's or sphere's radius, else half its height."""
    shapes = p.getCollisionShapeData(body, joint, physicsClientId=client)  # type: ignore[attr-defined]
    if not shapes:
        info = p.getJointInfo(body, joint, physicsClientId=client)  # type: ignore[attr-defined]
        raise ScenarioError(f"{urdf}: the link {info[12].decode()!r} of wheel joint {info[1].decode()!r} has no "
                            "collision shape, so it cannot touch the ground; give it a <collision> or name the "
                            "joint of a wheel that has one", source=source, field=f"scenario.robot.{side}")
    kind, dimensions = shapes[0][2], shapes[0][3]
    if kind in (_GEOM_CYLINDER, _GEOM_CAPSULE):
        return float(dimensions[1])
    if kind == _GEOM_SPHERE:
        return float(dimensions[0])
    low, high = p.getAABB(body, joint, physicsClientId=client)  # type: ignore[attr-defined]
    return float(high[2] - low[2]) / 2.0
