"""Small worlds for the MuJoCo engine's tests, and the shipped worlds switched to MuJoCo."""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

from pytest_ddenv.sim import Run
from pytest_ddenv.world import Ground, Model, Physics, Pose, Scenario, Shape, World

WORLDS = Path(__file__).resolve().parents[2] / "worlds"
MUJOCO = Physics(engine="mujoco")


def in_mujoco(world: World) -> World:
    """`world` with `physics: {engine: mujoco}`."""
    return dataclasses.replace(world, physics=dataclasses.replace(world.physics, engine="mujoco"))


def shipped(name: str) -> World:
    """A shipped world (worlds/NAME.yaml) in MuJoCo."""
    return in_mujoco(World.load(WORLDS / f"{name}.yaml"))


def box(name: str, size: tuple[float, float, float], at: tuple[float, float, float], *, static: bool = True,
        mass: float | None = None, mu: float = 1.0) -> Model:
    return Model(name, (Shape("box", size=size),), pose=Pose(*at), static=static, mass=mass, mu=mu)


def flat_world(*models: Model, goal: tuple[float, float] = (10.0, 0.0), timeout: float = 30.0,
               start: Pose = Pose(), ground: Ground | None = Ground()) -> World:
    """The Husky at `start` driving to `goal` among `models`, in MuJoCo."""
    return World(models=tuple(models), physics=MUJOCO, ground=ground, name="test",
                 scenario=Scenario(robot="husky", start=start, goal=(goal[0], goal[1], None), timeout=timeout))


def far_boxes() -> tuple[Model, Model]:
    """An untouched static box and an untouched dynamic box, far from the robot's path."""
    return (box("far_static", (1.0, 1.0, 1.0), (50.0, 40.0, 0.5)),
            box("far_dynamic", (0.5, 0.5, 0.5), (-40.0, 60.0, 0.25), static=False, mass=3.0))


def digest(run: Run) -> str:
    """sha1 of the run's poses, velocities and wheel loads."""
    return hashlib.sha1(run.poses.tobytes() + run.velocities.tobytes() + run.wheel_contacts.tobytes()).hexdigest()
