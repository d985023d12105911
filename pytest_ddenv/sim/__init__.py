"""Simulation layer: the Husky (or your robot) in PyBullet or MuJoCo, driven by a controller (the built-in
go-to-goal law or yours), with seeded noise, sensors and predicates.

`Simulator` runs worlds one after another, each in the physics engine its `physics.engine` names (the seam:
sim/physics.py); `simulate` is a one-shot convenience that reuses a per-process simulator. See
docs/simulation.md.
"""

from __future__ import annotations

from collections.abc import Sequence

from pytest_ddenv.errors import ControllerError, ControllerTimeout
from pytest_ddenv.oracle.predicates import Predicate
from pytest_ddenv.sim.arm.robot import ArmRobot
from pytest_ddenv.sim.control import (
    Command,
    Controller,
    ControllerLike,
    LaserScan,
    Observation,
    WheelCommand,
)
from pytest_ddenv.sim.engine import Simulator
from pytest_ddenv.sim.episode import Episode
from pytest_ddenv.sim.robot import ROBOTS, Husky, Robot, WheeledRobot, register_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import NoiseSettings, RunSettings
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.model import World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

__all__ = [
    "ROBOTS",
    "ArmRobot",
    "Command",
    "Controller",
    "ControllerError",
    "ControllerLike",
    "ControllerTimeout",
    "Episode",
    "Husky",
    "LaserScan",
    "NoiseSettings",
    "Observation",
    "Robot",
    "Run",
    "RunSettings",
    "Simulator",
    "WheelCommand",
    "WheeledRobot",
    "register_robot",
    "simulate",
]

_shared: Simulator | None = None


def simulate(
    world: World,
    *,
    seed: int = 0,
    predicates: Sequence[Predicate] = (),
    settings: RunSettings = RunSettings(),
    timeout: float | None = None,
    controller: ControllerLike | None = None,
    max_wall_time: float | None = None,
) -> Run:
    """Run `world` once with a simulator shared by this process (created on first use)."""
    return shared_simulator().run(world, seed=seed, predicates=predicates, settings=settings, timeout=timeout,
                                  controller=controller, max_wall_time=max_wall_time)


def shared_simulator() -> Simulator:
    """This process's simulator (created on first use, kept alive)."""
    global _shared
    if _shared is None or _shared.closed:
        _shared = Simulator()
    return _shared
