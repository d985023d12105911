"""A wheeled URDF robot in MuJoCo: the URDF compiled by MuJoCo itself, then a free joint, ellipsoid wheels,
velocity actuators with the robot's torque limit (each wheel joint with its servo's armature), and every robot
geom in `ROBOT_GROUP` (the laser and the support rays leave it out).

MuJoCo's URDF reader refuses xacro leftovers such as the Husky's `$(optenv HUSKY_IMU_RPY 0 -1.5708 3.1416)`
("bad format in attribute 'xyz'"), so each `$(optenv NAME default)` becomes `default` in a copy of the text,
and a `<mujoco><compiler .../></mujoco>` element keeps MuJoCo from welding the root to the world
(`fusestatic` off) and drops the visual meshes (`discardvisual`).
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim.mujoco.contacts import ROBOT_GROUP, ROLLING, TORSION, friction_priority
from pytest_ddenv.sim.robot import Husky, WheeledRobot
from pytest_ddenv.sim.urdf_mujoco import mujoco_readable_urdf

PREFIX = "robot/"
"""Every name of the robot in the compiled model starts with this."""
ROOT_JOINT = "root"
DEFAULT_MU = 0.5
"""pybullet's lateralFriction for a link whose URDF gives none (the Husky's chassis)."""
VELOCITY_GAIN = 200.0
"""The Husky's wheel actuators' gain, N m s/rad: a velocity servo clamped at the torque limit (pybullet's
velocity motor is a hard constraint limited by the same torque; straight driving is the same in both)."""
SERVO_STEPS = 5.0
"""Another robot's wheel servo has the time constant (wheel inertia / gain) of a fifth of a time step: a gain
of 200 on a light wheel (the example diffbot's 0.0016 kg m^2) saturates at the torque limit, spins the wheel
up past its target in one step and makes the robot hop."""

# pybullet's merged Husky chassis (base_link with the fixed links, each link without <inertial> weighing 1 kg):
# mass, centre of mass from base_link's frame, principal inertia. The same robot in both engines.
HUSKY_CHASSIS = (39.455, (0.006893929793435562, 0.0, 0.1568947699911291 - 0.14493),
                 (1.317943838358333, 3.588822229795833, 4.429161649195833))


def robot_spec(robot: WheeledRobot) -> mujoco.MjSpec:
    """The robot alone, as a spec to attach to a world: its root body free, its wheels driven."""
    try:
        spec = mujoco.MjSpec.from_string(mujoco_readable_urdf(robot.urdf))
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
    friction = link_friction(robot.urdf)
    for geom in spec.geoms:
        wheel = geom.parent.name in wheel_bodies
        mu = friction.get(geom.parent.name, DEFAULT_MU)
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


def tune_wheel_servos(model: mujoco.MjModel, robot: WheeledRobot) -> None:
    """Each wheel actuator's gain in the compiled `model` (the Husky's `VELOCITY_GAIN`, else `SERVO_STEPS`
    times the wheel's inertia about its axis per time step), and the wheel joint's armature: the servo as the
    contact solver sees it (`servo_armature`)."""
    timestep = float(model.opt.timestep)
    for name in robot.wheel_names:
        actuator = model.actuator(PREFIX + name).id
        dof = int(model.jnt_dofadr[model.joint(PREFIX + name).id])
        inertia = float(model.dof_M0[dof])
        gain = VELOCITY_GAIN if isinstance(robot, Husky) else SERVO_STEPS * inertia / timestep
        model.actuator_gainprm[actuator, 0] = gain
        model.actuator_biasprm[actuator, 2] = -gain
        model.dof_armature[dof] = servo_armature(gain, timestep)


def servo_armature(gain: float, timestep: float) -> float:
    """The inertia (kg m^2) a velocity servo of `gain` (N m s/rad) adds to its wheel in one implicit step,
    `gain * timestep`, given to the wheel joint as armature so that the contact solver sees it.

    pybullet's velocity motor is a constraint solved with the contacts: within its torque limit it holds the
    wheel's speed, so the friction that turns a skid-steered robot pushes against a wheel that does not give.
    MuJoCo's velocity actuator is a force outside the contact solver, whose effective mass of a wheel contact
    is the bare wheel's (the Husky's 0.025 kg m^2: 0.8 kg at the rim): it stopped a slipping wheel with a
    fraction of mu N, and the Husky turned 17 degrees in 3 s at 0.8 rad/s on the spot, against 57 in pybullet
    (88 with this armature; straight driving unchanged; docs/scenarios-tuning.md, "In MuJoCo")."""
    return gain * timestep


def link_friction(urdf: str) -> dict[str, float]:
    """Link name -> its `<contact><lateral_friction value=...>`, which pybullet applies and MuJoCo ignores."""
    import defusedxml.ElementTree

    root = defusedxml.ElementTree.fromstring(Path(urdf).read_text(encoding="utf-8"))
    found = {}
    for link in root.iter("link"):
        element = link.find("contact/lateral_friction")
        if element is not None and element.get("value") is not None:
            found[str(link.get("name"))] = float(str(element.get("value")))
    return found


def _husky_chassis(spec: mujoco.MjSpec) -> None:
    base = spec.body("base_link")
    mass, centre, inertia = HUSKY_CHASSIS
    base.explicitinertial = True
    base.mass = mass
    base.ipos = list(centre)
    base.iquat = [1.0, 0.0, 0.0, 0.0]
    base.inertia = list(inertia)
    base.fullinertia = [float("nan")] * 6
