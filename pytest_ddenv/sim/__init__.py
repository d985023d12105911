"""Simulation layer: the Husky (or your robot) in PyBullet, with seeded noise, sensors and predicates.

`Simulator` owns one pybullet DIRECT client and runs worlds one after another; `simulate` is a one-shot
convenience that reuses a per-process simulator. See docs/simulation.md.
"""

from __future__ import annotations

from collections.abc import Sequence

from pytest_ddenv.oracle import Predicate
from pytest_ddenv.sim.engine import Simulator
from pytest_ddenv.sim.robot import ROBOTS, Husky, Robot, register_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import NoiseSettings, RunSettings
from pytest_ddenv.world import World

__all__ = [
    "ROBOTS",
    "Husky",
    "NoiseSettings",
    "Robot",
    "Run",
    "RunSettings",
    "Simulator",
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
) -> Run:
    """Run `world` once with a simulator shared by this process (created on first use)."""
    global _shared
    if _shared is None or _shared.client < 0:
        _shared = Simulator()
    return _shared.run(world, seed=seed, predicates=predicates, settings=settings, timeout=timeout)
