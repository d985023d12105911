"""The engine seam: what a run asks of a physics engine, and which engine runs a world.

`Simulator` and `Episode` talk to the physics only through a `PhysicsEngine`: build the world (with the
robot, when the engine compiles them together), spawn the robot, step, read the robot's pose, velocity and
contacts, cast rays. Everything else (noise, controllers, predicates, the `Run`) is engine-neutral.
Two implementations: `PybulletPhysics` (sim/pybullet_physics.py) and `MujocoPhysics` (sim/mujoco/);
sim/engine_choice.py makes the one a world names.

Bodies are named by engine-specific integer keys; `bodies` maps each key of the world to its model name
(the ground: `GROUND_BODY_NAME`). A robot's links are integer keys too, the robot's `wheel_links` and
`link_names` (-1 is the base).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.world.model import World

Vector = tuple[float, float, float]
BaseState = tuple[Vector, Vector, Vector, Vector]
"""The robot base's position, (roll, pitch, yaw), linear and angular velocity, all in the world frame."""
RayHit = tuple[int, float]
"""(body key hit, or -1 for none; fraction of the ray from its start to its end)."""
ContactPoint = tuple[int, int, float]
"""(robot link, other body key, normal force N) of one contact point of the robot."""
ContactPosition = tuple[int, int, Vector, float]
"""(robot link, other body key, the point on the other body, normal force N)."""


class PhysicsEngine(Protocol):
    """One physics engine's world, rebuilt for every run (`load`), then driven tick by tick."""

    name: str
    version: str

    @property
    def bodies(self) -> Mapping[int, str]:
        """Body key -> model name (the ground: `GROUND_BODY_NAME`) of the loaded world."""

    def load(self, world: World, robot: Robot, friction: str) -> None:
        """Forget the previous run and build `world` (gravity, time step, ground, models) for `robot`."""

    def support_heights(self, rays_from: list[list[float]], rays_to: list[list[float]]) -> list[float]:
        """z of the first world surface each ray meets (rays that meet none are left out); the robot is not
        in the world yet or is not seen."""

    def spawn(self, robot: Robot, position: Vector, yaw: float) -> tuple[Robot, int]:
        """Put `robot`'s base frame at `position`, heading `yaw`; the robot the episode drives, its body key."""

    def start_contacts(self) -> list[tuple[int, float]]:
        """(other body key, signed distance, < 0 inside) of each contact point of the robot just spawned."""

    def base_state(self) -> BaseState:
        """The robot base now: pybullet's convention, the chassis's centre of mass."""

    def robot_contacts(self) -> list[ContactPoint]:
        """The robot's contact points now, in the engine's order."""

    def step(self, count: int) -> None:
        """Advance the simulation `count` time steps."""

    def cast_rays(self, starts: list[list[float]], ends: list[list[float]]) -> list[RayHit]:
        """The first body each segment meets, leaving out the robot's own geometry where the engine can."""

    def body_pose(self, body: int) -> tuple[Sequence[float], Sequence[float]]:
        """A model body's position and (x, y, z, w) quaternion."""

    def joint_positions(self) -> list[float]:
        """The robot's joint positions, in its joint order."""

    def contact_positions(self) -> list[ContactPosition]:
        """The robot's contact points with where they touch the other body."""

    def close(self) -> None:
        """Release the engine's resources."""
