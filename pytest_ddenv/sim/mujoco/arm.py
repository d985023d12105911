"""An arm in a compiled MuJoCo world: `arm_world` (a world with the arm of `arm_spec.py`, compiled) and
`MujocoArm` (the `DrivenArm` of sim/arm/driven.py: its joints, gripper, inverse kinematics and contacts), with
`MujocoArmRobot`, the robot `MujocoPhysics.spawn` gives the episode.

pybullet's motor limits a joint's speed to the URDF's `velocity`; MuJoCo's position actuator cannot, so each
setpoint moves towards its target at that speed, one time step at a time (`MujocoArm.advance`, before every
step). Inverse kinematics is damped least squares on `mj_jacBody`, on a scratch copy of the state.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.arm_state import GRIPPER_OPEN
from pytest_ddenv.sim.arm.driven import Quaternion, Vector
from pytest_ddenv.sim.mujoco.arm_camera import ray_picture
from pytest_ddenv.sim.mujoco.arm_spec import GRIPPER, IMPRATIO, SATURATION, SERVO_STEP, arm_spec
from pytest_ddenv.sim.mujoco.driven_robot import NOT_ROBOT, touching
from pytest_ddenv.sim.mujoco.robot_spec import PREFIX
from pytest_ddenv.sim.mujoco.world_spec import world_spec
from pytest_ddenv.sim.physics import BaseState
from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.world.model import ArmDescription, Camera, World

IK_ITERATIONS = 100
IK_RESIDUAL = 1e-4
"""m (and rad for the orientation): inverse kinematics stops below this error."""
IK_DAMPING = 0.05
"""The damping of the damped least squares step (m, rad)."""
IK_REST = 0.05
"""The weight of the step towards the home pose in the null space of the end effector's task."""


def arm_world(world: World, description: ArmDescription, friction: str, *, velocities: Sequence[float],
              home: Sequence[float]) -> MujocoArm:
    """`world` with the arm in it, compiled, its servos tuned (`MujocoArm.tune_servos`), not yet placed."""
    spec = world_spec(world, arm_spec(description, world.source, float(world.physics.timestep)), PREFIX, friction)
    spec.option.impratio = IMPRATIO
    try:
        model = spec.compile()
    except ValueError as error:
        raise ScenarioError(f"MuJoCo cannot compile the world: {error}", source=world.source) from None
    arm = MujocoArm(description, model, mujoco.MjData(model), velocities=velocities, home=home)
    arm.tune_servos()
    return arm


class MujocoArm:
    """The arm of one compiled model (a `DrivenArm`): `velocities` are the arm and finger joints' speed
    limits (rad/s, m/s), `home` the arm joints' positions at the start."""

    def __init__(self, description: ArmDescription, model: mujoco.MjModel, data: mujoco.MjData, *,
                 velocities: Sequence[float], home: Sequence[float]) -> None:
        self.model, self.data = model, data
        self.joint_names = tuple(description.arm_joints)
        arm = [model.joint(PREFIX + name).id for name in description.arm_joints]
        fingers = [model.joint(PREFIX + name).id for name in description.finger_joints]
        self._qpos = np.array([model.jnt_qposadr[j] for j in arm], dtype=np.int64)
        self._dofs = np.array([model.jnt_dofadr[j] for j in arm], dtype=np.int64)
        self._finger_qpos = np.array([model.jnt_qposadr[j] for j in fingers], dtype=np.int64)
        self._actuators = np.array([model.actuator(PREFIX + n).id for n in (*description.arm_joints, GRIPPER)],
                                   dtype=np.int64)
        ranges = model.jnt_range[arm]
        self.lower = tuple(float(v) for v in ranges[:, 0])
        self.upper = tuple(float(v) for v in ranges[:, 1])
        self._finger_range = model.jnt_range[fingers].copy()
        self.max_opening = float(self._finger_range[:, 1].sum())
        self._home = np.array(home, dtype=np.float64)
        self._all_qpos = np.concatenate([self._qpos, self._finger_qpos])
        speeds = np.asarray(velocities, dtype=np.float64)[:len(arm) + 1]  # the gripper: the first finger's
        self._step_limit = speeds * float(model.opt.timestep)
        self._targets = np.zeros(len(self._actuators))
        self.root = int(model.jnt_bodyid[arm[0]])
        while int(model.body_parentid[self.root]) != 0:
            self.root = int(model.body_parentid[self.root])
        bodies = [b for b in range(model.nbody) if int(model.body_rootid[b]) == self.root]
        self.link_names: Mapping[int, str] = {b - self.root - 1: model.body(b).name.removeprefix(PREFIX)
                                              for b in bodies}
        """pybullet's link indices: the root -1, then the bodies in the URDF's order."""
        self.finger_links = frozenset(int(model.jnt_bodyid[j]) - self.root - 1 for j in fingers)
        self._ee = model.body(PREFIX + description.end_effector).id
        self._geom_link = [int(model.geom_bodyid[g]) - self.root - 1 if int(model.geom_bodyid[g]) in bodies
                           else NOT_ROBOT for g in range(model.ngeom)]
        weld = {b - self.root - 1: int(model.body_weldid[b]) for b in bodies}
        self._adjacent = {(a, b) for a in weld for b in weld
                          if weld[a] == weld[b] or int(model.body_parentid[weld[a]]) == weld[b]
                          or int(model.body_parentid[weld[b]]) == weld[a]}
        self._scratch = mujoco.MjData(model)
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))

    def tune_servos(self) -> None:
        """Each servo's stiffness and damping in the compiled model (sim/mujoco/arm_spec.py), critically damped
        with the joint-space inertia at the home pose."""
        model = self.model
        scratch = mujoco.MjData(model)
        scratch.qpos[self._qpos] = self._home
        mujoco.mj_forward(model, scratch)
        inertias = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, scratch, inertias)
        timestep = float(model.opt.timestep)
        for actuator in self._actuators:
            dof = int(model.jnt_dofadr[model.actuator_trnid[actuator, 0]])
            inertia = float(inertias[dof, dof])
            effort = float(model.actuator_forcerange[actuator, 1]) if model.actuator_forcelimited[actuator] else 0.0
            stiffness = effort / SATURATION if effort > 0 else inertia * (SERVO_STEP / timestep) ** 2
            model.actuator_gainprm[actuator, 0] = stiffness
            model.actuator_biasprm[actuator, 1] = -stiffness
            model.actuator_biasprm[actuator, 2] = -2.0 * math.sqrt(stiffness * inertia)

    # -- placing and stepping (the engine's) -----------------------------------------------------------
    def place(self, position: Vector, yaw: float) -> None:
        """The base at `position` turned by `yaw`, the arm at its home pose with the gripper open, at rest."""
        model, data = self.model, self.data
        model.body_pos[self.root] = position
        model.body_quat[self.root] = [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]
        data.qpos[self._qpos] = self._home
        data.qpos[self._finger_qpos] = self._finger_range[:, 1]
        data.qvel[:] = 0.0
        self._targets[:] = [*self._home, self._finger_range[0, 1]]
        data.ctrl[self._actuators] = self._targets
        mujoco.mj_forward(model, data)

    def advance(self) -> None:
        """Before one time step: each actuator's setpoint one step closer to its target, at the joint's
        speed limit."""
        ctrl = self.data.ctrl[self._actuators]
        self.data.ctrl[self._actuators] = ctrl + np.clip(self._targets - ctrl, -self._step_limit, self._step_limit)

    # -- the DrivenArm interface -----------------------------------------------------------------------
    def joint_state(self) -> tuple[list[float], list[float]]:
        return ([float(v) for v in self.data.qpos[self._qpos]], [float(v) for v in self.data.qvel[self._dofs]])

    def end_effector(self) -> tuple[Vector, Quaternion]:
        """From the joint positions now (`joint_state`), computed on a scratch copy."""
        scratch = self._scratch
        scratch.qpos[:] = self.data.qpos
        mujoco.mj_kinematics(self.model, scratch)
        x, y, z = (float(v) for v in scratch.xpos[self._ee])
        w, qx, qy, qz = (float(v) for v in scratch.xquat[self._ee])
        return (x, y, z), (qx, qy, qz, w)

    def end_effector_velocity(self) -> tuple[Vector, Vector]:
        """The end effector's linear and angular velocity now (world frame), from the joints' state now."""
        scratch = self._scratch
        scratch.qpos[:], scratch.qvel[:] = self.data.qpos, self.data.qvel
        mujoco.mj_kinematics(self.model, scratch)
        mujoco.mj_comPos(self.model, scratch)
        mujoco.mj_comVel(self.model, scratch)
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, scratch, mujoco.mjtObj.mjOBJ_BODY, self._ee, velocity, 0)
        (wx, wy, wz), (vx, vy, vz) = velocity[:3].tolist(), velocity[3:].tolist()
        return (vx, vy, vz), (wx, wy, wz)

    def camera_image(self, camera: Camera, colors: Mapping[int, Sequence[float]]) -> NDArray[np.generic]:
        """The picture of `camera` now, ray cast (sim/mujoco/arm_camera.py)."""
        return ray_picture(self.model, self.data, camera, colors)

    def gripper_opening(self) -> float:
        return float(self.data.qpos[self._finger_qpos].sum())

    def set_joint_targets(self, positions: Sequence[float]) -> None:
        clipped = np.clip(np.asarray(positions, dtype=np.float64), self.lower, self.upper)
        self._targets[:len(self._qpos)] = clipped

    def set_gripper(self, action: str) -> None:
        self._targets[-1] = self._finger_range[0, 1 if action == GRIPPER_OPEN else 0]

    def inverse_kinematics(self, position: Vector, orientation: Quaternion) -> list[float]:
        """Damped least squares on `mj_jacBody` from the joint positions now, on a scratch copy of the state,
        with a step towards the home pose in the task's null space; clipped to the limits each iteration."""
        model, scratch = self.model, self._scratch
        scratch.qpos[:] = self.data.qpos
        goal = np.asarray(position, dtype=np.float64)
        qx, qy, qz, qw = orientation
        goal_quat = np.array([qw, qx, qy, qz], dtype=np.float64) / math.sqrt(qw**2 + qx**2 + qy**2 + qz**2)
        turn, error = np.zeros(3), np.zeros(6)
        identity = np.eye(len(self._dofs))
        for _ in range(IK_ITERATIONS):
            mujoco.mj_kinematics(model, scratch)
            mujoco.mj_comPos(model, scratch)
            error[:3] = goal - scratch.xpos[self._ee]
            mujoco.mju_subQuat(turn, goal_quat, scratch.xquat[self._ee])
            error[3:] = scratch.xmat[self._ee].reshape(3, 3) @ turn
            if np.linalg.norm(error) < IK_RESIDUAL:
                break
            mujoco.mj_jacBody(model, scratch, self._jacp, self._jacr, self._ee)
            jacobian = np.vstack([self._jacp[:, self._dofs], self._jacr[:, self._dofs]])
            damped = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + IK_DAMPING**2 * np.eye(6), error)
            joints = scratch.qpos[self._qpos]
            null_space = identity - np.linalg.pinv(jacobian) @ jacobian
            step = damped + null_space @ (IK_REST * (self._home - joints))
            scratch.qpos[self._qpos] = np.clip(joints + step, self.lower, self.upper)
        return [float(v) for v in scratch.qpos[self._qpos]]

    def self_contacts(self) -> list[tuple[int, int]]:
        pairs: set[tuple[int, int]] = set()
        for index in range(self.data.ncon):
            contact = self.data.contact[index]
            first, second = self._geom_link[int(contact.geom1)], self._geom_link[int(contact.geom2)]
            if NOT_ROBOT in (first, second):
                continue
            a, b = sorted((first, second))
            if (a, b) in self._adjacent or (a in self.finger_links and b in self.finger_links):
                continue
            pairs.add((a, b))
        return sorted(pairs)

    # -- what the engine reads -------------------------------------------------------------------------
    def touching(self, geom1: int, geom2: int) -> tuple[int, int] | None:
        """(arm link, other body id) when exactly one of the two geoms is the arm's."""
        return touching(self.model, self._geom_link, geom1, geom2)

    def base_state(self) -> BaseState:
        """The base's pose (its body origin), at rest."""
        x, y, z = (float(v) for v in self.data.xpos[self.root])
        w, qx, qy, qz = (float(v) for v in self.data.xquat[self.root])
        yaw = math.atan2(2.0 * (w * qz + qx * qy), 1.0 - 2.0 * (qy**2 + qz**2))
        return (x, y, z), (0.0, 0.0, yaw), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)

    def joint_positions(self) -> list[float]:
        return [float(v) for v in self.data.qpos[self._all_qpos]]


class MujocoArmRobot(Robot):
    """The robot `MujocoPhysics.spawn` returns for an `ArmRobot`: its `arm` is the `MujocoArm`
    (sim/arm/driven.py says what the episode reads)."""

    def __init__(self, described: Robot, arm: MujocoArm) -> None:
        self.described, self.arm = described, arm
        self.name, self.footprint, self.base_height = described.name, described.footprint, described.base_height
        self.has_laser = False

    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        raise NotImplementedError("MujocoPhysics.spawn places a MuJoCo arm")

    @property
    def wheel_links(self) -> tuple[int, ...]:
        return ()

    @property
    def link_names(self) -> Mapping[int, str]:
        return self.arm.link_names

    @property
    def mass(self) -> float:
        return float(self.arm.model.body_subtreemass[self.arm.root])

    def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        self.described.drive(linear, angular, scale_left, scale_right)  # an arm refuses a mobile robot's command

    def measured_velocity(self) -> tuple[float, float]:
        return 0.0, 0.0
