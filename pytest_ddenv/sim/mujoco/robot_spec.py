"""A wheeled URDF robot in MuJoCo: the URDF compiled by MuJoCo itself, then a free joint, ellipsoid wheels,
velocity actuators with the robot's torque limit, and every robot geom in `ROBOT_GROUP` (the laser and the
support rays leave it out).

MuJoCo's URDF reader refuses xacro leftovers such as the Husky's `$(optenv HUSKY_IMU_RPY 0 -1.5708 3.1416)`
("bad format in attribute 'xyz'"), so each `$(optenv NAME default)` becomes `default` in a copy of the text,
and a `<mujoco><compiler .../></mujoco>` element keeps MuJoCo from welding the root to the world
(`fusestatic` off) and drops the visual meshes (`discardvisual`).
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim.mujoco.contacts import ROBOT_GROUP, ROLLING, TORSION, friction_priority
from pytest_ddenv.sim.robot import Husky, WheeledRobot

PREFIX = "robot/"
"""Every name of the robot in the compiled model starts with this."""
ROOT_JOINT = "root"
WHEEL_MU = 1.0
"""The wheels' friction (the Husky URDF's lateral_friction; pybullet's engine uses the same)."""
CHASSIS_MU = 0.5
"""pybullet's default lateralFriction for a link without `<contact>`: the chassis's friction."""
VELOCITY_GAIN = 200.0
"""The wheel actuators' gain, N m s/rad: a velocity servo clamped at the torque limit (pybullet's velocity
motor is a hard constraint limited by the same torque; straight driving is the same in both)."""

# pybullet's merged Husky chassis (base_link with the fixed links, each link without <inertial> weighing 1 kg):
# mass, centre of mass from base_link's frame, principal inertia. The same robot in both engines.
HUSKY_CHASSIS = (39.455, (0.006893929793435562, 0.0, 0.1568947699911291 - 0.14493),
                 (1.317943838358333, 3.588822229795833, 4.429161649195833))


def sanitised_urdf(path: str) -> str:
    """The URDF's text as MuJoCo can read it (see the module docstring)."""
    text = Path(path).read_text(encoding="utf-8")
    text = re.sub(r"\$\(optenv\s+\S+\s+([^)]*)\)", r"\1", text)
    folder = str(Path(path).resolve().parent).replace('"', "&quot;")
    compiler = (f'<mujoco><compiler discardvisual="true" fusestatic="false" strippath="false" '
                f'meshdir="{folder}"/></mujoco>')
    return re.sub(r"(<robot\b[^>]*>)", lambda match: match.group(1) + compiler, text, count=1)


def robot_spec(robot: WheeledRobot) -> mujoco.MjSpec:
    """The robot alone, as a spec to attach to a world: its root body free, its wheels driven."""
    try:
        spec = mujoco.MjSpec.from_string(sanitised_urdf(robot.urdf))
    except (ValueError, OSError) as error:
        raise ScenarioError(f"MuJoCo cannot read the URDF {robot.urdf}: {error}", source=robot.source,
                            field="scenario.robot.urdf") from None
    root = spec.worldbody.first_body()
    root.add_freejoint(name=ROOT_JOINT)
    wheel_bodies = {}
    for name in robot.wheel_names:
        joint = spec.joint(name)
        if joint is None:
            raise ScenarioError(f"{robot.urdf} has no joint {name!r} for MuJoCo", source=robot.source,
                                field="scenario.robot")
        wheel_bodies[joint.parent.name] = name
    if isinstance(robot, Husky):  # pybullet's mass model: the same robot in both engines
        _husky_chassis(spec)
    for geom in spec.geoms:
        wheel = geom.parent.name in wheel_bodies
        mu = WHEEL_MU if wheel else CHASSIS_MU
        geom.group = ROBOT_GROUP
        geom.friction = [mu, TORSION, ROLLING]
        geom.priority = friction_priority(mu)
        geom.condim = 3
        if wheel and geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER:
            # an ellipsoid of the wheel's radius and width: MuJoCo's cylinder-box contact gives face normals on a
            # box edge, so a wheel between two terrain pads is squeezed sideways and stalls (docs/simulation.md)
            radius, half_width = float(geom.size[0]), float(geom.size[1])
            geom.type = mujoco.mjtGeom.mjGEOM_ELLIPSOID
            geom.size = [radius, radius, half_width]
    for name in robot.wheel_names:
        actuator = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_velocity(kv=VELOCITY_GAIN)
        actuator.forcelimited = True
        actuator.forcerange = [-robot.max_force, robot.max_force]
        actuator.ctrllimited = False
    return spec


def _husky_chassis(spec: mujoco.MjSpec) -> None:
    base = spec.body("base_link")
    mass, centre, inertia = HUSKY_CHASSIS
    base.explicitinertial = True
    base.mass = mass
    base.ipos = list(centre)
    base.iquat = [1.0, 0.0, 0.0, 0.0]
    base.inertia = list(inertia)
    base.fullinertia = [float("nan")] * 6
