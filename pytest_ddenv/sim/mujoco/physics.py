"""`MujocoPhysics`: the MuJoCo engine behind the seam (sim/physics.py).

Every run compiles the world and its robot into a new model (world_spec.py; a few ms up to 200 models),
then places the robot. Body keys are MuJoCo body ids; the robot's links are -1 (the chassis: every body
of the robot that is not a wheel) and its wheels' indices in the robot's wheel order. The base pose is the
chassis's centre of mass (pybullet's convention), the velocity taken at that point. An arm (`ArmRobot`) is
compiled with the world by `arm.arm_world`: its link keys are pybullet's (the root -1, then the URDF's
links), `spawn` places its base and gives a `MujocoArmRobot` whose `arm` is the `MujocoArm`, and each time
step first moves its servos' setpoints (`MujocoArm.advance`).

What the engine reads after `step` (poses, velocities, contacts and their forces, rays) is the state MuJoCo
computed at the start of the last time step, all of one instant, 1/240 s behind the integrated state: an
extra `mj_forward` per tick would cost time and, with it, the rubble scenario's robot ends stuck with its
chassis on the cinder block rather than high-centred by the predicate's measure (docs/simulation.md).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim.arm.robot import ArmRobot
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.mujoco.arm import MujocoArm, MujocoArmRobot, arm_world
from pytest_ddenv.sim.mujoco.contacts import RAY_GROUPS
from pytest_ddenv.sim.mujoco.driven_robot import MujocoRobot
from pytest_ddenv.sim.mujoco.near import NearContacts
from pytest_ddenv.sim.mujoco.robot_spec import PREFIX, ROOT_JOINT, robot_spec, tune_wheel_servos
from pytest_ddenv.sim.mujoco.world_spec import world_spec
from pytest_ddenv.sim.physics import BaseState, ContactPoint, ContactPosition, RayHit, Vector
from pytest_ddenv.sim.robot import Robot, WheeledRobot
from pytest_ddenv.world.model import World

_RAY_GROUPS = np.array(RAY_GROUPS, dtype=np.uint8)


class MujocoPhysics:
    """One compiled MuJoCo model and its data, rebuilt by `load` for every run."""

    name = "mujoco"

    def __init__(self) -> None:
        mujoco.set_mju_user_warning(_warn)  # not MuJoCo's default, which writes MUJOCO_LOG.TXT into the cwd
        self.version = str(mujoco.__version__)
        self.model: mujoco.MjModel | None = None
        self.data: mujoco.MjData | None = None
        self._bodies: dict[int, str] = {}
        self._robot: MujocoRobot | MujocoArm | None = None
        self._arm_robot: MujocoArmRobot | None = None
        self._near: NearContacts | None = None
        self._geom_id = np.zeros(1, dtype=np.int32)

    @property
    def bodies(self) -> Mapping[int, str]:
        return self._bodies

    def close(self) -> None:
        self.model = self.data = None
        self._robot = self._arm_robot = None

    # -- the world -------------------------------------------------------------------------------------
    def load(self, world: World, robot: Robot, friction: str) -> None:
        if isinstance(robot, ArmRobot):
            speeds = [joint.velocity for joint in (*robot.joints, *robot.fingers)]
            arm = arm_world(world, robot.description, friction, velocities=speeds, home=robot.home)
            self._arm_robot = MujocoArmRobot(robot, arm)
            self._loaded_model(world, arm.model, arm.data, arm)
            return
        if not isinstance(robot, WheeledRobot):
            raise ScenarioError(f"the robot {robot.name!r} is a pybullet robot (a Robot subclass that spawns "
                                "itself in pybullet); the mujoco engine runs URDF wheeled robots "
                                "(WheeledRobot, a world file's robot mapping) and arms (ArmRobot)", source=world.source,
                                field="physics.engine")
        spec = world_spec(world, robot_spec(robot), PREFIX, friction)
        try:
            model = spec.compile()
        except ValueError as error:
            raise ScenarioError(f"MuJoCo cannot compile the world: {error}", source=world.source) from None
        tune_wheel_servos(model, robot)
        data = mujoco.MjData(model)
        self._arm_robot = None
        self._loaded_model(world, model, data, MujocoRobot(robot, model, data))

    def _loaded_model(self, world: World, model: mujoco.MjModel, data: mujoco.MjData,
                      robot: MujocoRobot | MujocoArm) -> None:
        self.model, self.data, self._robot = model, data, robot
        # an arm's contacts are MuJoCo's alone: pybullet listed no near contact of the Panda's (its fingertips
        # 9 mm above the table while closing on a cube), where near.py's would list the table
        near = robot.geoms_near_listed() if isinstance(robot, MujocoRobot) else ([], [], [])
        self._near = NearContacts(model, *near)
        names = set(world.names)
        self._bodies = {b: model.body(b).name for b in range(1, model.nbody) if model.body(b).name in names}
        if world.ground is not None:
            self._bodies[0] = GROUND_BODY_NAME
        mujoco.mj_kinematics(model, self.data)

    def _loaded(self) -> tuple[mujoco.MjModel, mujoco.MjData, MujocoRobot | MujocoArm]:
        if self.model is None or self.data is None or self._robot is None:
            raise RuntimeError("no world is loaded in this MuJoCo engine")
        return self.model, self.data, self._robot

    def support_heights(self, rays_from: list[list[float]], rays_to: list[list[float]]) -> list[float]:
        hits = self.cast_rays(rays_from, rays_to)
        return [start[2] + fraction * (end[2] - start[2])
                for start, end, (body, fraction) in zip(rays_from, rays_to, hits, strict=True) if body >= 0]

    def cast_rays(self, starts: list[list[float]], ends: list[list[float]]) -> list[RayHit]:
        model, data, _ = self._loaded()
        hits: list[RayHit] = []
        for start, end in zip(starts, ends, strict=True):
            origin = np.asarray(start, dtype=np.float64)
            direction = np.asarray(end, dtype=np.float64) - origin
            fraction = mujoco.mj_ray(model, data, origin, direction, _RAY_GROUPS, 1, -1, self._geom_id)
            if fraction < 0 or fraction > 1:
                hits.append((-1, 1.0))
            else:
                hits.append((int(model.geom_bodyid[self._geom_id[0]]), float(fraction)))
        return hits

    # -- the robot -------------------------------------------------------------------------------------
    def spawn(self, robot: Robot, position: Vector, yaw: float) -> tuple[Robot, int]:
        model, data, driven = self._loaded()
        if isinstance(driven, MujocoArm):
            assert self._arm_robot is not None
            driven.place(position, yaw)
            return self._arm_robot, driven.root
        address = int(model.jnt_qposadr[model.joint(PREFIX + ROOT_JOINT).id])
        data.qpos[address:address + 3] = position
        data.qpos[address + 3:address + 7] = [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]
        mujoco.mj_forward(model, data)
        return driven, driven.root

    def start_contacts(self) -> list[tuple[int, float]]:
        _, data, driven = self._loaded()
        found = []
        for index in range(data.ncon):
            contact = data.contact[index]
            pair = driven.touching(int(contact.geom1), int(contact.geom2))
            if pair is not None:
                found.append((pair[1], float(contact.dist)))
        return found

    def base_state(self) -> BaseState:
        return self._loaded()[2].base_state()

    def robot_contacts(self) -> list[ContactPoint]:
        return [(link, other, force) for link, other, _, force in self.contact_positions()]

    def contact_positions(self) -> list[ContactPosition]:
        model, data, driven = self._loaded()
        found: list[ContactPosition] = []
        force = np.zeros(6)
        for index in range(data.ncon):
            contact = data.contact[index]
            pair = driven.touching(int(contact.geom1), int(contact.geom2))
            if pair is None:
                continue
            mujoco.mj_contactForce(model, data, index, force)
            x, y, z = (float(v) for v in contact.pos)
            found.append((pair[0], pair[1], (x, y, z), float(force[0])))
        assert self._near is not None
        listed = {(link, other) for link, other, _, _ in found}
        found.extend((link, other, position, 0.0) for link, other, position in self._near.pairs(data, listed))
        return found

    def step(self, count: int) -> None:
        model, data, driven = self._loaded()
        if isinstance(driven, MujocoArm):  # the arm's setpoints move at the joints' speed limits, step by step
            for _ in range(count):
                driven.advance()
                mujoco.mj_step(model, data)
            return
        mujoco.mj_step(model, data, nstep=count)

    def body_pose(self, body: int) -> tuple[Sequence[float], Sequence[float]]:
        """As pybullet gives a base: its centre of mass (`xipos`), with the body's orientation."""
        _, data, _ = self._loaded()
        w, x, y, z = (float(v) for v in data.xquat[body])
        return [float(v) for v in data.xipos[body]], (x, y, z, w)

    def joint_positions(self) -> list[float]:
        return self._loaded()[2].joint_positions()


class MujocoWarning(RuntimeWarning):
    """A warning of MuJoCo's (an unstable simulation, a full contact buffer, ...)."""


def _warn(message: str) -> None:
    warnings.warn(f"MuJoCo: {message.strip()}", MujocoWarning, stacklevel=1)
