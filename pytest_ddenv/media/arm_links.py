"""Where an arm's links were during a run: its recorded joint positions (`Run.detail.joints`) put through
pybullet's forward kinematics, the arm standing at the scenario's start, for the 3D recording; and which
pybullet joint each recorded column is (`recorded_joints`, for the animations too)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.scenario.reported import REPORTED
from pytest_ddenv.sim.arm.robot import ArmRobot
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.robot import Robot, make_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.urdf_geometry import pybullet_installed
from pytest_ddenv.world.model import World


@dataclass(frozen=True, eq=False)
class ArmLinks:
    """`positions` (T, L + 1, 3): the arm's base (0) and its L links' frames (1..L, in pybullet's joint
    order) in the world at each recorded time; `parents` (L,): the index in `positions` of each link's
    parent (0: the base), so that (parent, link) pairs are the arm's bones; `names` (L,) the links'."""

    positions: NDArray[np.float64]
    parents: tuple[int, ...]
    names: tuple[str, ...]

    def bones(self, row: int) -> NDArray[np.float64]:
        """(L, 2, 3): each link's segment from its parent's frame at recorded time `row`."""
        frame = self.positions[row]
        return np.stack([frame[list(self.parents)], frame[1:]], axis=1)


def recorded_joints(p: Any, client: int, body: int, robot: Robot, width: int) -> list[int] | None:
    """The pybullet joint index of each of the `width` columns of a run's recorded joints (`RunDetail.joints`)
    of `robot` loaded as `body`: every joint in index order (what the PyBullet engine records), or an arm's
    arm joints then finger joints (what the MuJoCo engine records); None when neither fits."""
    count = p.getNumJoints(body, physicsClientId=client)
    if width == count:
        return list(range(count))
    if isinstance(robot, ArmRobot):
        names = (*robot.description.arm_joints, *robot.description.finger_joints)
        index = {p.getJointInfo(body, joint, physicsClientId=client)[1].decode(): joint for joint in range(count)}
        if width == len(names) and all(name in index for name in names):
            return [index[name] for name in names]
    return None


def arm_links(world: World, run: Run) -> ArmLinks | None:
    """Where the arm's links were at every recorded time; None when it cannot be had here (not an arm's run,
    no joints recorded, no pybullet, or a robot that cannot be made here)."""
    detail, scenario = run.detail, world.scenario
    if run.robot_kind != "arm" or run.robot == REPORTED or detail is None or scenario is None:
        return None
    if not pybullet_installed() or not len(detail.joints):
        return None
    with silenced():
        import pybullet as p
    client = p.connect(p.DIRECT)
    try:
        start = scenario.start
        try:
            with silenced():
                robot = make_robot(scenario.robot, world.source)
                body = robot.spawn(client, (start.x, start.y, start.z), start.yaw)
        except Exception:  # noqa: BLE001 - a robot of the user's that cannot be made here: no links recorded
            return None
        links = p.getNumJoints(body, physicsClientId=client)
        columns = recorded_joints(p, client, body, robot, detail.joints.shape[1])
        if columns is None:
            return None
        infos = [p.getJointInfo(body, joint, physicsClientId=client) for joint in range(links)]
        base = (start.x, start.y, start.z)  # where the base's frame was put (pybullet's base pose is its mass's)
        positions = np.empty((len(detail.joints), links + 1, 3))
        for row, angles in enumerate(detail.joints):
            for joint, angle in zip(columns, angles, strict=True):
                p.resetJointState(body, joint, float(angle), physicsClientId=client)
            states = p.getLinkStates(body, list(range(links)), computeForwardKinematics=True,
                                     physicsClientId=client)
            positions[row, 0] = base
            positions[row, 1:] = [state[4] for state in states]  # the link frames' world positions
        return ArmLinks(positions, tuple(int(info[16]) + 1 for info in infos),
                        tuple(info[12].decode() for info in infos))
    finally:
        p.disconnect(client)
