"""An arm as a MuJoCo spec to attach to a world (`arm_spec`): the MuJoCo side of sim/mujoco/arm.py.

The arm is its URDF compiled by MuJoCo (as the wheeled robots: `mujoco_readable_urdf`), or the description's
MJCF when it gives one (its own actuators removed), with its root body welded to the world. A URDF's links
get the inertia MuJoCo computes from their collision meshes, with the URDF's masses, as pybullet's `loadURDF`
does by default.

- Each arm joint has a position actuator clamped at its effort limit (the URDF's `effort`, MuJoCo's
  `actfrcrange`); the gripper is one actuator on the first finger clamped at the fingers' summed effort, the
  other fingers following it through joint equalities (a URDF's `<mimic>`, which pybullet ignores): each
  finger presses with its own effort limit. The arm's gravity is compensated through the actuators
  (`gravcomp`, `actgravcomp`: within the same limits), as pybullet's motor holds a joint against gravity.
- Each servo pushes with its effort limit at `SATURATION` from its setpoint (a closing finger presses at its
  effort limit; a joint holds against a contact), critically damped at the home pose (`arm.tune_arm_servos`).
  MuJoCo integrates a stiffness explicitly, so each driven joint gets the armature (rotor inertia) that keeps
  every motion of the servos under `SERVO_STEP` radians of oscillation per time step: without it the wrist
  (0.003 kg m^2 about its axis) and the shoulder and upper-arm joints, coaxial when the arm is stretched out,
  turned against each other at 37 rad/s. (A velocity servo, as pybullet's motor is, pressed a stalled finger
  with a fraction of its effort limit or, stiffer, went bang-bang at its force limit.)
- Contacts: the fingers' have torsional friction and are stiffer (`_contacts`), and a world with an arm runs
  MuJoCo's no-slip solver (`NOSLIP_ITERATIONS`, `IMPRATIO`; set by `arm.arm_world`).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim.mujoco.contacts import ROBOT_GROUP, ROLLING, TORSION, friction_priority
from pytest_ddenv.sim.mujoco.robot_spec import DEFAULT_MU, link_friction
from pytest_ddenv.sim.urdf_mujoco import mujoco_readable_urdf
from pytest_ddenv.world.files import resolve_relative
from pytest_ddenv.world.model import ArmDescription

FIELD = "scenario.robot"
GRIPPER = "gripper"
"""The actuator of the fingers (on the first finger joint; the others follow it through equalities)."""
SATURATION = 0.01
"""rad or m from its setpoint, a servo pushes with its joint's effort limit."""
SERVO_STEP = 0.5
"""The most a servo may turn in one time step (its natural frequency times the step), on its armature alone."""
FINGER_SOLREF = (0.01, 1.0)
"""The fingers' contacts: stiffer than MuJoCo's default (0.02 s), as stiff as a 240 Hz step allows."""
NOSLIP_ITERATIONS = 3
IMPRATIO = 10.0
"""A world with an arm: MuJoCo's no-slip solver passes and the ratio of frictional to normal impedance. With
MuJoCo's defaults (soft friction) a held cube crept along the finger pads while the arm swung it and fell out
within three moves that pybullet's held it through (tests/sim_mujoco/test_arm.py)."""


def arm_spec(description: ArmDescription, source: str | None, timestep: float) -> mujoco.MjSpec:
    """The arm alone, as a spec to attach to a world: its root body fixed, its joints driven (see the module
    docstring); ScenarioError naming the field when MuJoCo cannot read the file or a named joint or link is
    not in it."""
    field = f"{FIELD}.mjcf" if description.mjcf else f"{FIELD}.urdf"
    path = str(resolve_relative(description.mjcf or description.urdf, source))
    try:
        spec = (mujoco.MjSpec.from_file(path) if description.mjcf
                else mujoco.MjSpec.from_string(mujoco_readable_urdf(path)))
    except (ValueError, OSError) as error:
        raise ScenarioError(f"MuJoCo cannot read the arm {path}: {error}", source=source, field=field) from None
    arm, fingers = (_joints(spec, names, path, source, f"{FIELD}.{key}") for key, names in
                    (("arm_joints", description.arm_joints), ("finger_joints", description.finger_joints)))
    if spec.body(description.end_effector) is None:
        raise ScenarioError(f"the arm {path} has no body {description.end_effector!r} for MuJoCo (a URDF link "
                            "without inertia is merged into its parent unless it is the end effector)",
                            source=source, field=f"{FIELD}.end_effector")
    if not description.mjcf:
        _inertia_from_geoms(spec)
    _contacts(spec, {joint.parent.name for joint in fingers}, None if description.mjcf else link_friction(path))
    for body in spec.bodies:
        body.gravcomp = 1.0
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    for joint in arm:
        _drive(spec, joint.name, joint, _effort(joint), timestep)
    _drive(spec, GRIPPER, fingers[0], sum(_effort(joint) for joint in fingers), timestep)
    names = {joint.name for joint in fingers}
    for equality in list(spec.equalities):
        if equality.type == mujoco.mjtEq.mjEQ_JOINT and {equality.name1, equality.name2} <= names:
            spec.delete(equality)
    for joint in fingers[1:]:
        spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=joint.name, name2=fingers[0].name,
                          data=[0.0, 1.0] + [0.0] * 10)
    return spec


def _joints(spec: mujoco.MjSpec, names: Sequence[str], path: str, source: str | None,
            field: str) -> list[mujoco.MjsJoint]:
    found = []
    for name in names:
        joint = spec.joint(name)
        if joint is None:
            raise ScenarioError(f"the arm {path} has no joint {name!r} for MuJoCo", source=source, field=field)
        found.append(joint)
    return found


def _contacts(spec: mujoco.MjSpec, finger_bodies: set[str], friction: dict[str, float] | None) -> None:
    """Every arm geom in `ROBOT_GROUP`; a URDF's links with their `<lateral_friction>` (`friction`: None for
    an MJCF, whose own contact parameters stay); the fingers with torsional friction (`condim` 4) and stiffer
    contacts (`FINGER_SOLREF`)."""
    for geom in spec.geoms:
        geom.group = ROBOT_GROUP
        mu = float(geom.friction[0]) if friction is None else friction.get(geom.parent.name, DEFAULT_MU)
        finger = geom.parent.name in finger_bodies
        if friction is not None:
            geom.friction = [mu, TORSION, ROLLING]
            geom.priority = friction_priority(mu)
            geom.condim = 3
        if finger:
            geom.condim = 4
            geom.solref = list(FINGER_SOLREF)


def _effort(joint: mujoco.MjsJoint) -> float:
    """The joint's effort limit (a URDF's `effort`, MuJoCo's `actfrcrange`; 0: none)."""
    return float(max(abs(joint.actfrcrange[0]), abs(joint.actfrcrange[1]))) if joint.actfrclimited else 0.0


def _drive(spec: mujoco.MjSpec, name: str, joint: mujoco.MjsJoint, effort: float, timestep: float) -> None:
    """A position actuator on `joint` clamped at `effort`, the joint's gravity compensated through it, and the
    joint's armature (see the module docstring); the gains are set on the compiled model (`tune_arm_servos`)."""
    joint.actgravcomp = True
    actuator = spec.add_actuator(name=name, target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.set_to_position(kp=1.0, kv=1.0)
    actuator.ctrllimited = False
    if effort > 0:
        actuator.forcelimited = True
        actuator.forcerange = [-effort, effort]
        joint.armature = max(float(joint.armature), effort / SATURATION * (timestep / SERVO_STEP) ** 2)


def _inertia_from_geoms(spec: mujoco.MjSpec) -> None:
    """Each body's inertia as MuJoCo computes it from its collision geoms, with the URDF's mass: pybullet's
    `loadURDF` ignores a URDF's inertia tensors unless told otherwise and computes them from the collision
    shapes (the shipped Panda's are 0.1 kg m^2 on every link, some 100 times its meshes', and made the wrist
    lag the shoulder's turns and fling a held cube)."""
    alone = spec.copy()
    for body in alone.bodies:
        geoms = [geom for geom in alone.geoms if geom.parent.name == body.name]
        for geom in geoms:
            geom.mass = body.mass / len(geoms)
    alone.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
    model = alone.compile()
    with_geoms = {geom.parent.name for geom in spec.geoms}
    for body in spec.bodies:
        if body.name not in with_geoms and body.mass == 0:  # the Panda's link8 and grasp target weighed 0.1 kg m^2
            body.inertia, body.fullinertia = [0.0, 0.0, 0.0], [float("nan")] * 6
        elif body.name in with_geoms:
            compiled = model.body(body.name)
            body.explicitinertial = True
            body.ipos, body.iquat = compiled.ipos.tolist(), compiled.iquat.tolist()
            body.inertia, body.fullinertia = compiled.inertia.tolist(), [float("nan")] * 6
