"""`PybulletArm`: an arm in a pybullet world (the `DrivenArm` of sim/arm/driven.py).

Position control of every arm joint at its URDF effort and velocity limits, the gripper's fingers driven
together as one command at their effort limit, inverse kinematics by `p.calculateInverseKinematics` (with the
joint limits, and the home pose as the rest pose of its null space).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.oracle.arm_state import GRIPPER_OPEN
from pytest_ddenv.sim.arm.driven import CAMERA_FAR, CAMERA_NEAR, Quaternion, Vector
from pytest_ddenv.world.model import Camera

IK_ITERATIONS = 100
IK_RESIDUAL = 1e-4
"""m: pybullet's IK stops iterating below this end-effector error."""
FINGER_FRICTION = 1.0
"""Lateral friction of the fingers' pads (pybullet's default 0.5 lets a held box slide out)."""


@dataclass(frozen=True)
class JointInfo:
    """One joint of a loaded URDF, as pybullet reports it."""

    index: int
    lower: float
    upper: float
    effort: float
    velocity: float


class PybulletArm:
    """An arm body in a pybullet client (see the module docstring). Made by `ArmRobot.spawn`."""

    def __init__(self, client: int, body: int, *, arm_joints: Sequence[JointInfo], finger_joints: Sequence[JointInfo],
                 joint_names: Sequence[str], end_effector: int, link_names: Mapping[int, str],
                 parents: Mapping[int, int], home: Sequence[float]) -> None:
        import pybullet as p

        self._p, self._client, self._body = p, client, body
        self._arm, self._fingers = tuple(arm_joints), tuple(finger_joints)
        self.joint_names: tuple[str, ...] = tuple(joint_names)
        self.lower: tuple[float, ...] = tuple(j.lower for j in self._arm)
        self.upper: tuple[float, ...] = tuple(j.upper for j in self._arm)
        self.link_names: Mapping[int, str] = dict(link_names)
        self.finger_links: frozenset[int] = frozenset(j.index for j in self._fingers)
        self.max_opening: float = sum(j.upper for j in self._fingers)
        self._ee = end_effector
        self._parents = dict(parents)
        self._home = [float(v) for v in home]
        self._painted = False
        self._movable = sorted([*self._arm, *self._fingers], key=lambda j: j.index)
        """Every joint pybullet's IK solves for (its degrees of freedom, in index order)."""
        for finger in self._fingers:
            p.changeDynamics(body, finger.index, lateralFriction=FINGER_FRICTION, physicsClientId=client)

    def joint_state(self) -> tuple[list[float], list[float]]:
        states = self._p.getJointStates(self._body, [j.index for j in self._arm], physicsClientId=self._client)
        return [float(s[0]) for s in states], [float(s[1]) for s in states]

    def end_effector(self) -> tuple[Vector, Quaternion]:
        state = self._p.getLinkState(self._body, self._ee, computeForwardKinematics=1, physicsClientId=self._client)
        x, y, z = state[4]
        qx, qy, qz, qw = state[5]
        return (x, y, z), (qx, qy, qz, qw)

    def end_effector_velocity(self) -> tuple[Vector, Vector]:
        """The end effector's linear and angular velocity now (world frame)."""
        state = self._p.getLinkState(self._body, self._ee, computeLinkVelocity=1, computeForwardKinematics=1,
                                     physicsClientId=self._client)
        (vx, vy, vz), (wx, wy, wz) = state[6], state[7]
        return (vx, vy, vz), (wx, wy, wz)

    def gripper_opening(self) -> float:
        states = self._p.getJointStates(self._body, [j.index for j in self._fingers], physicsClientId=self._client)
        return float(sum(s[0] for s in states))

    def reset_joints(self, positions: Sequence[float]) -> None:
        """Put the arm joints at `positions` and the gripper open, at rest (before the first step), and hold
        them there."""
        p, client = self._p, self._client
        for joint, value in zip(self._arm, positions, strict=True):
            p.resetJointState(self._body, joint.index, float(value), physicsClientId=client)
        for finger in self._fingers:
            p.resetJointState(self._body, finger.index, finger.upper, physicsClientId=client)
        self.set_joint_targets(positions)
        self.set_gripper(GRIPPER_OPEN)

    def set_joint_targets(self, positions: Sequence[float]) -> None:
        p, client = self._p, self._client
        for joint, value in zip(self._arm, positions, strict=True):
            target = min(max(float(value), joint.lower), joint.upper)
            p.setJointMotorControl2(self._body, joint.index, p.POSITION_CONTROL, targetPosition=target,
                                    force=joint.effort, maxVelocity=joint.velocity, physicsClientId=client)

    def set_gripper(self, action: str) -> None:
        p, client = self._p, self._client
        for finger in self._fingers:
            target = finger.upper if action == GRIPPER_OPEN else finger.lower
            p.setJointMotorControl2(self._body, finger.index, p.POSITION_CONTROL, targetPosition=target,
                                    force=finger.effort, maxVelocity=finger.velocity, physicsClientId=client)

    def inverse_kinematics(self, position: Vector, orientation: Quaternion) -> list[float]:
        p = self._p
        lower = [j.lower for j in self._movable]
        upper = [j.upper for j in self._movable]
        ranges = [hi - lo for lo, hi in zip(lower, upper, strict=True)]
        rest_of = {j.index: value for j, value in zip(self._arm, self._home, strict=True)}
        rest = [rest_of.get(j.index, j.upper) for j in self._movable]
        solution = p.calculateInverseKinematics(
            self._body, self._ee, list(position), list(orientation), lowerLimits=lower, upperLimits=upper,
            jointRanges=ranges, restPoses=rest, maxNumIterations=IK_ITERATIONS, residualThreshold=IK_RESIDUAL,
            physicsClientId=self._client,
        )
        by_index = {j.index: float(v) for j, v in zip(self._movable, solution, strict=True)}
        return [min(max(by_index[j.index], j.lower), j.upper) for j in self._arm]

    def camera_image(self, camera: Camera, colors: Mapping[int, Sequence[float]]) -> NDArray[np.generic]:
        """The picture of `camera` now, drawn by pybullet's TinyRenderer: (H, W, 3) uint8 RGB, or (H, W)
        float32 depth (m along the view axis). `colors`: body key -> RGBA of the world's bodies, painted
        before the first picture (their visual shapes only: nothing of the physics changes)."""
        p = self._p
        if not self._painted:
            for body, rgba in colors.items():
                for link in range(-1, p.getNumJoints(body, physicsClientId=self._client)):
                    p.changeVisualShape(body, link, rgbaColor=list(rgba), physicsClientId=self._client)
            self._painted = True
        direction = np.subtract(camera.look_at, camera.position)
        vertical = abs(direction[2]) > 0.99 * float(np.linalg.norm(direction))
        view = p.computeViewMatrix(list(camera.position), list(camera.look_at), [1.0, 0.0, 0.0] if vertical
                                   else [0.0, 0.0, 1.0], physicsClientId=self._client)
        projection = p.computeProjectionMatrixFOV(camera.fov, camera.width / camera.height, CAMERA_NEAR, CAMERA_FAR,
                                                  physicsClientId=self._client)
        _, _, rgba, depth, _ = p.getCameraImage(camera.width, camera.height, view, projection,
                                                renderer=p.ER_TINY_RENDERER, physicsClientId=self._client)
        if camera.kind == "depth":
            buffer = np.asarray(depth, dtype=np.float64).reshape(camera.height, camera.width)
            metres = CAMERA_FAR * CAMERA_NEAR / (CAMERA_FAR - (CAMERA_FAR - CAMERA_NEAR) * buffer)
            return metres.astype(np.float32)
        return np.asarray(rgba, dtype=np.uint8).reshape(camera.height, camera.width, 4)[:, :, :3].copy()

    def self_contacts(self) -> list[tuple[int, int]]:
        pairs: set[tuple[int, int]] = set()
        for point in self._p.getContactPoints(bodyA=self._body, bodyB=self._body, physicsClientId=self._client):
            a, b = sorted((int(point[3]), int(point[4])))
            if a == b or self._parents.get(b) == a or self._parents.get(a) == b:
                continue
            if a in self.finger_links and b in self.finger_links:  # the gripper closed on nothing
                continue
            pairs.add((a, b))
        return sorted(pairs)
