"""Where an arm's links were during a run: its recorded joint positions (`Run.detail.joints`) put through
pybullet's forward kinematics, the arm standing at the scenario's start, for the 3D recording."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.scenario.reported import REPORTED
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.robot import make_robot
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
                body = make_robot(scenario.robot, world.source).spawn(client, (start.x, start.y, start.z), start.yaw)
        except Exception:  # noqa: BLE001 - a robot of the user's that cannot be made here: no links recorded
            return None
        links = p.getNumJoints(body, physicsClientId=client)
        if detail.joints.shape[1] != links:
            return None
        infos = [p.getJointInfo(body, joint, physicsClientId=client) for joint in range(links)]
        base = (start.x, start.y, start.z)  # where the base's frame was put (pybullet's base pose is its mass's)
        positions = np.empty((len(detail.joints), links + 1, 3))
        for row, angles in enumerate(detail.joints):
            for joint, angle in enumerate(angles):
                p.resetJointState(body, joint, float(angle), physicsClientId=client)
            states = p.getLinkStates(body, list(range(links)), computeForwardKinematics=True,
                                     physicsClientId=client)
            positions[row, 0] = base
            positions[row, 1:] = [state[4] for state in states]  # the link frames' world positions
        return ArmLinks(positions, tuple(int(info[16]) + 1 for info in infos),
                        tuple(info[12].decode() for info in infos))
    finally:
        p.disconnect(client)
