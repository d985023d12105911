"""Small worlds built in Python for the simulation tests."""

from __future__ import annotations

import hashlib

from pytest_ddenv.world import Ground, Model, Pose, Scenario, Shape, World


def box(name: str, size: tuple[float, float, float], at: tuple[float, float, float], *, static: bool = True,
        mass: float | None = None, mu: float = 1.0) -> Model:
    return Model(name, (Shape("box", size=size),), pose=Pose(*at), static=static, mass=mass, mu=mu)


def flat_world(*models: Model, goal: tuple[float, float] = (10.0, 0.0), timeout: float = 30.0,
               start: Pose = Pose(), start_z_given: bool = False, ground: Ground | None = Ground(),
               robot: str = "husky", goal_tolerance: float = 0.3) -> World:
    return World(
        models=tuple(models),
        scenario=Scenario(robot=robot, start=start, start_z_given=start_z_given, goal=(goal[0], goal[1], None),
                          goal_tolerance=goal_tolerance, timeout=timeout),
        ground=ground,
        name="test",
    )


def far_boxes() -> tuple[Model, Model]:
    """An untouched static box and an untouched dynamic box, far from the robot's path."""
    return (
        box("far_static", (1.0, 1.0, 1.0), (50.0, 40.0, 0.5)),
        box("far_dynamic", (0.5, 0.5, 0.5), (-40.0, 60.0, 0.25), static=False, mass=3.0),
    )


def ditch_world(*, near: bool = True, far: bool = True, timeout: float = 20.0) -> World:
    """Two 0.88 m high plateaus with a 0.5 m gap between them (the paper's ditch, simplified)."""
    models = []
    if near:
        models.append(box("near", (10.0, 6.0, 0.88), (-3.5, 0.0, 0.44)))
    if far:
        models.append(box("far", (10.0, 6.0, 0.88), (7.0, 0.0, 0.44)))
    return flat_world(*models, start=Pose(-3.0, 0.0), goal=(5.0, 0.0), timeout=timeout)


def digest(run: object) -> str:
    poses = run.poses
    velocities = run.velocities
    return hashlib.sha1(poses.tobytes() + velocities.tobytes()).hexdigest()
