"""SimulationPool: same Runs as a serial Simulator, concurrent callers, errors that cross the boundary."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import os
import pickle
from collections.abc import Iterator
from pathlib import Path

import pytest

from pytest_ddenv.errors import DdenvError, ScenarioError
from pytest_ddenv.execution import SimulationError, SimulationPool
from pytest_ddenv.oracle import PREDICATES, make_predicate
from pytest_ddenv.robot_world import RobotFailure, RobotWorld
from pytest_ddenv.sim import Run, Simulator
from pytest_ddenv.world import World

from .conftest import STUCK, reduce_with


@pytest.fixture(scope="module")
def pool() -> Iterator[SimulationPool]:
    with SimulationPool(2, watchdog=120.0) as pool:
        yield pool


def identical(a: Run, b: Run) -> bool:
    return (
        a.same_trajectory(b)
        and a.failure == b.failure
        and a.reached_goal == b.reached_goal
        and a.steps == b.steps
        and dict(a.first_touch) == dict(b.first_touch)
        and dict(a.first_sensed) == dict(b.first_sensed)
    )


def test_parallel_runs_are_bit_identical_to_serial_runs(pool: SimulationPool, wall_world: World) -> None:
    worlds = [wall_world, wall_world.without(["wall"]), wall_world.select(["wall", "ball"])]
    jobs = [(w, seed) for w in worlds for seed in (0, 7)]
    with concurrent.futures.ThreadPoolExecutor(4) as threads:
        parallel = list(threads.map(lambda job: pool.simulate(job[0], seed=job[1], predicates=STUCK), jobs))
    with Simulator() as simulator:
        serial = [simulator.run(w, seed=seed, predicates=[make_predicate("stuck", window=2.0, min_progress=0.2)])
                  for w, seed in jobs]
    assert all(identical(a, b) for a, b in zip(parallel, serial, strict=True))
    assert parallel[0].failure is not None and parallel[2].failure is None  # the wall blocks; without it, no
    assert pool.stats.probes >= len(jobs) and pool.stats.errors == 0


def test_the_reduction_on_two_workers_finds_the_wall(pool: SimulationPool, wall_world: World) -> None:
    with SimulationPool(1) as serial_pool:
        serial = reduce_with(serial_pool.simulate, wall_world, workers=1)
    parallel = reduce_with(pool.simulate, wall_world, workers=2)
    assert serial.minimal == parallel.minimal == ("wall",)
    assert parallel.one_minimal and parallel.errors == 0


def test_workers_are_persistent_processes(pool: SimulationPool, wall_world: World) -> None:
    pids = pool.pids
    assert len(pids) == 2 and os.getpid() not in pids
    for seed in range(3):
        pool.simulate(wall_world.select(["ball"]), seed=seed, timeout=0.5)
    assert pool.pids == pids


def test_errors_of_the_simulation_cross_the_boundary_unchanged(pool: SimulationPool, wall_world: World) -> None:
    no_scenario = World(models=wall_world.models, name="no-scenario")
    with pytest.raises(ScenarioError, match="has no scenario") as raised:
        pool.simulate(no_scenario, seed=0)
    assert raised.value.field == "scenario"
    with pytest.raises(ScenarioError, match="seed"):
        pool.simulate(wall_world, seed=-1)
    assert pool.stats.errors == 0  # the simulation's own errors are not pool errors


def test_robot_world_runs_on_the_pool(pool: SimulationPool, wall_world: World) -> None:
    robot_world = RobotWorld(wall_world, predicates=STUCK, seed=0, simulate=pool.simulate)
    with pytest.raises(RobotFailure, match="stuck"):
        robot_world.run()
    assert robot_world.runs[-1].failure is not None


def test_in_process_pool_has_no_worker_process(wall_world: World) -> None:
    with SimulationPool(1) as pool:
        assert pool.in_process and pool.pids == []
        run = pool.simulate(wall_world, seed=0, predicates=STUCK)
    assert run.failure is not None
    with pytest.raises(SimulationError, match="closed"):
        pool.simulate(wall_world, seed=0)


def test_simulation_error_is_a_ddenv_error() -> None:
    assert issubclass(SimulationError, DdenvError)


def test_preloaded_modules_register_custom_robots_in_the_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wall_world: World
) -> None:
    (tmp_path / "ddenv_twin_robot.py").write_text(
        "from pytest_ddenv.sim import Husky, register_robot\nregister_robot('husky_twin', Husky, replace=True)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert wall_world.scenario is not None
    twin = dataclasses.replace(wall_world, scenario=dataclasses.replace(wall_world.scenario, robot="husky_twin"))
    with SimulationPool(2) as plain, pytest.raises(ScenarioError, match="unknown robot 'husky_twin'"):
        plain.simulate(twin, seed=0)
    with SimulationPool(2, preload=["ddenv_twin_robot"]) as pool:
        assert pool.simulate(twin, seed=0, predicates=STUCK).failure is not None


@pytest.mark.parametrize("name", sorted(PREDICATES))
def test_every_built_in_predicate_crosses_the_process_boundary(name: str) -> None:
    """RobotWorld hands built predicate objects to `simulate`: they must pickle (specs always do)."""
    predicate = make_predicate(name)
    assert type(pickle.loads(pickle.dumps(predicate))) is type(predicate)
