"""`PybulletPhysics`: the pybullet engine behind the seam (sim/physics.py), one DIRECT client.

These are the calls the simulator made before the seam existed, in the same order with the same arguments,
so that PyBullet runs stay bit-identical (collision detection and contact queries touch Bullet's manifolds:
no query is added or moved).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from pytest_ddenv.sim.builder import build_world
from pytest_ddenv.sim.physics import BaseState, ContactPoint, ContactPosition, RayHit, Vector
from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.world.model import World


class PybulletPhysics:
    """A pybullet DIRECT client; `load` resets it for every run."""

    name = "pybullet"

    def __init__(self) -> None:
        from pytest_ddenv.sim.quiet import silenced

        with silenced():  # importing pybullet prints its build time on the C-level stdout
            import pybullet as p

            self.client: int = p.connect(p.DIRECT)
        self._p = p
        if self.client < 0:  # pragma: no cover
            raise RuntimeError("could not start a pybullet DIRECT client")
        self.version = str(p.getAPIVersion())
        try:
            from importlib.metadata import version

            self.version = version("pybullet")
        except Exception:  # noqa: BLE001, S110 - any failure keeps getAPIVersion()  # pragma: no cover
            pass
        self._bodies: dict[int, str] = {}
        self._robot = -1

    @property
    def bodies(self) -> Mapping[int, str]:
        return self._bodies

    def close(self) -> None:
        if self.client >= 0:
            try:
                self._p.disconnect(physicsClientId=self.client)
            except Exception:  # noqa: BLE001, S110 - the client is already gone  # pragma: no cover
                pass
            self.client = -1

    def load(self, world: World, robot: Robot, friction: str) -> None:
        p, client = self._p, self.client
        p.resetSimulation(physicsClientId=client)
        physics = world.physics
        p.setGravity(*physics.gravity, physicsClientId=client)
        p.setPhysicsEngineParameter(
            fixedTimeStep=float(physics.timestep), numSolverIterations=int(physics.solver_iterations),
            deterministicOverlappingPairs=1, physicsClientId=client,
        )
        self._bodies = build_world(p, client, world, friction)
        self._robot = -1

    def support_heights(self, rays_from: list[list[float]], rays_to: list[list[float]]) -> list[float]:
        hits = self._p.rayTestBatch(rays_from, rays_to, numThreads=1, physicsClientId=self.client)
        return [hit[3][2] for hit in hits if hit[0] >= 0]

    def spawn(self, robot: Robot, position: Vector, yaw: float) -> tuple[Robot, int]:
        self._robot = robot.spawn(self.client, position, yaw)
        return robot, self._robot

    def start_contacts(self) -> list[tuple[int, float]]:
        p, client = self._p, self.client
        p.performCollisionDetection(physicsClientId=client)
        return [(point[2], point[8]) for point in p.getContactPoints(bodyA=self._robot, physicsClientId=client)]

    def base_state(self) -> BaseState:
        p, client, body = self._p, self.client, self._robot
        position, orientation = p.getBasePositionAndOrientation(body, physicsClientId=client)
        rpy = p.getEulerFromQuaternion(orientation)
        linear, angular = p.getBaseVelocity(body, physicsClientId=client)
        return position, rpy, linear, angular

    def robot_contacts(self) -> list[ContactPoint]:
        return [(point[3], point[2], point[9])
                for point in self._p.getContactPoints(bodyA=self._robot, physicsClientId=self.client)]

    def step(self, count: int) -> None:
        for _ in range(count):
            self._p.stepSimulation(physicsClientId=self.client)

    def cast_rays(self, starts: list[list[float]], ends: list[list[float]]) -> list[RayHit]:
        hits = self._p.rayTestBatch(starts, ends, numThreads=1, physicsClientId=self.client)
        return [(hit[0], hit[2]) for hit in hits]

    def body_pose(self, body: int) -> tuple[Sequence[float], Sequence[float]]:
        position, orientation = self._p.getBasePositionAndOrientation(body, physicsClientId=self.client)
        return position, orientation

    def joint_positions(self) -> list[float]:
        p, client = self._p, self.client
        count = p.getNumJoints(self._robot, physicsClientId=client)
        states = p.getJointStates(self._robot, range(count), physicsClientId=client) if count else []
        return [float(state[0]) for state in states]

    def contact_positions(self) -> list[ContactPosition]:
        return [(point[3], point[2], point[6], point[9])
                for point in self._p.getContactPoints(bodyA=self._robot, physicsClientId=self.client)]
