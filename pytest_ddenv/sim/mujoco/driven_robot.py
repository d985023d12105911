"""`MujocoRobot`: a `WheeledRobot` as MuJoCo drives it (wheel actuators, encoders, the base's state)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from pytest_ddenv.sim.mujoco.robot_spec import PREFIX, ROOT_JOINT
from pytest_ddenv.sim.physics import BaseState
from pytest_ddenv.sim.robot import Robot, WheeledRobot
from pytest_ddenv.world.geometry import rpy_from_matrix

CHASSIS = -1
"""The link key of every robot body that is not a wheel."""
NOT_ROBOT = -2


class MujocoRobot(Robot):
    """The robot of one compiled model: its kinematics are the `WheeledRobot`'s, its motors MuJoCo's."""

    def __init__(self, robot: WheeledRobot, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.described, self.model, self.data = robot, model, data
        self.name, self.footprint, self.base_height = robot.name, robot.footprint, robot.base_height
        self.has_laser = robot.has_laser
        self.laser_height, self.laser_min_range = robot.laser_height, robot.laser_min_range
        self.laser_x, self.laser_y, self.laser_yaw = robot.laser_x, robot.laser_y, robot.laser_yaw
        self.wheel_radius, self.track, self.track_factor = robot.wheel_radius, robot.track, robot.track_factor
        robot.wheel_motors = self._set_wheel_speeds  # the described robot's commands drive MuJoCo's motors
        self.root = int(model.jnt_bodyid[model.joint(PREFIX + ROOT_JOINT).id])
        joints = [model.joint(PREFIX + name).id for name in robot.wheel_names]
        self._actuators = [model.actuator(PREFIX + name).id for name in robot.wheel_names]
        self._wheel_dofs = [int(model.jnt_dofadr[j]) for j in joints]
        wheel_bodies = [int(model.jnt_bodyid[j]) for j in joints]
        self._sides = [name in robot.left for name in robot.wheel_names]
        in_robot = [int(model.body_rootid[b]) == self.root for b in range(model.nbody)]
        self._chassis = [b for b in range(model.nbody) if in_robot[b] and _welded_to(model, b, self.root)]
        self._links = {CHASSIS: model.body(self.root).name.removeprefix(PREFIX)}
        self._links.update({i: model.body(b).name.removeprefix(PREFIX) for i, b in enumerate(wheel_bodies)})
        link_of_body = {b: CHASSIS for b in range(model.nbody) if in_robot[b]}
        link_of_body.update({b: i for i, b in enumerate(wheel_bodies)})
        self._geom_link = [link_of_body.get(int(model.geom_bodyid[g]), NOT_ROBOT) for g in range(model.ngeom)]
        self._hinges = [int(model.jnt_qposadr[j]) for j in range(model.njnt)
                        if in_robot[int(model.jnt_bodyid[j])] and model.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE]
        self._mass = float(model.body_subtreemass[self.root]) if robot._known_mass is None else robot._known_mass

    # -- the Robot interface ---------------------------------------------------------------------------
    def spawn(self, client: int, position: tuple[float, float, float], yaw: float) -> int:
        raise NotImplementedError("MujocoPhysics.spawn places a MuJoCo robot")

    @property
    def wheel_links(self) -> tuple[int, ...]:
        return tuple(range(len(self._actuators)))

    @property
    def link_names(self) -> Mapping[int, str]:
        return self._links

    @property
    def mass(self) -> float:
        return self._mass

    def drive(self, linear: float, angular: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        self.described.drive(linear, angular, scale_left, scale_right)  # a subclass's own drive() too

    def drive_wheels(self, left: float, right: float, scale_left: float = 1.0, scale_right: float = 1.0) -> None:
        self.described.drive_wheels(left, right, scale_left, scale_right)

    def _set_wheel_speeds(self, left: float, right: float) -> None:
        self.data.ctrl[self._actuators] = [left if is_left else right for is_left in self._sides]

    def odometry(self) -> tuple[tuple[float, ...], float, float]:
        return self.described.odometry_of(tuple(float(self.data.qvel[dof]) for dof in self._wheel_dofs))

    def measured_velocity(self) -> tuple[float, float]:
        _, linear, angular = self.odometry()
        return linear, angular

    # -- what the engine reads -------------------------------------------------------------------------
    def touching(self, geom1: int, geom2: int) -> tuple[int, int] | None:
        """(robot link, other body id) when exactly one of the two geoms is the robot's."""
        return touching(self.model, self._geom_link, geom1, geom2)

    def geoms_near_listed(self) -> tuple[list[int], list[int], list[int]]:
        """The robot's geoms, the robot link of each, and the geoms of everything else but planes (the ground
        is never a model)."""
        robot = [g for g, link in enumerate(self._geom_link) if link != NOT_ROBOT]
        others = [g for g, link in enumerate(self._geom_link)
                  if link == NOT_ROBOT and self.model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE]
        return robot, [self._geom_link[g] for g in robot], others

    def base_state(self) -> BaseState:
        """The chassis's centre of mass (pybullet's base position), the root's orientation, and the velocity
        at that point, in the world frame."""
        model, data = self.model, self.data
        masses = model.body_mass[self._chassis]
        points = data.xipos[self._chassis]
        total = float(masses.sum())
        centre = (masses @ points) / total if total > 0 else data.xpos[self.root].copy()
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, self.root, velocity, 0)
        angular = velocity[:3]
        linear = velocity[3:] + np.cross(angular, centre - data.xipos[self.root])
        roll, pitch, yaw = rpy_from_matrix(data.xmat[self.root].reshape(3, 3))
        x, y, z = (float(v) for v in centre)
        vx, vy, vz = (float(v) for v in linear)
        wx, wy, wz = (float(v) for v in angular)
        return (x, y, z), (roll, pitch, yaw), (vx, vy, vz), (wx, wy, wz)

    def joint_positions(self) -> list[float]:
        return [float(self.data.qpos[address]) for address in self._hinges]


def _welded_to(model: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether `body` moves with `root` (no joint on the way up to it)."""
    while body != root:
        if model.body_jntnum[body] > 0 or body == 0:
            return False
        body = int(model.body_parentid[body])
    return True


def touching(model: mujoco.MjModel, geom_link: Sequence[int], geom1: int, geom2: int) -> tuple[int, int] | None:
    """(robot link, other body id) of a contact when exactly one of its two geoms is the robot's (`geom_link`:
    each geom's robot link, or `NOT_ROBOT`)."""
    link1, link2 = geom_link[geom1], geom_link[geom2]
    if link1 != NOT_ROBOT and link2 == NOT_ROBOT:
        return link1, int(model.geom_bodyid[geom2])
    if link2 != NOT_ROBOT and link1 == NOT_ROBOT:
        return link2, int(model.geom_bodyid[geom1])
    return None
