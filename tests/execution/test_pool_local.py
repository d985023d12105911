"""LocalPool: the same runs as in this process, concurrent callers, errors that cross the boundary, user code
imported by every worker."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import os
import pickle
from collections.abc import Iterator
from pathlib import Path

import pytest

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.execution import LocalPool, WorkerError, WorkerStartError
from pytest_ddenv.oracle import PREDICATES, make_predicate
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE
from pytest_ddenv.sim import Run, Simulator
from pytest_ddenv.world import World

from .conftest import reduce_with, run_of, stuck_job


@pytest.fixture(scope="module")
def pool() -> Iterator[LocalPool]:
    with LocalPool(stuck_job(), 2, watchdog=120.0) as pool:
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


def test_parallel_runs_are_bit_identical_to_serial_runs(pool: LocalPool, wall_world: World) -> None:
    worlds = [wall_world, wall_world.without(["wall"]), wall_world.select(["wall", "ball"])]
    probes = [(w, attempt) for w in worlds for attempt in (0, 7)]
    with concurrent.futures.ThreadPoolExecutor(4) as threads:
        parallel = [run_of(r) for r in threads.map(lambda probe: pool.call(*probe), probes)]
    with Simulator() as simulator:
        serial = [simulator.run(w, seed=attempt * ATTEMPT_SEED_STRIDE,
                                predicates=[make_predicate("stuck", window=2.0, min_progress=0.2)])
                  for w, attempt in probes]
    assert all(identical(a, b) for a, b in zip(parallel, serial, strict=True))
    assert parallel[0].failure is not None and parallel[2].failure is None  # the wall blocks; without it, no
    assert pool.stats.probes >= len(probes) and pool.stats.errors == 0


@pytest.mark.slow  # a real reduction in worker processes: the full tier only
def test_the_reduction_on_two_workers_finds_the_wall(pool: LocalPool, wall_world: World) -> None:
    job = stuck_job()
    with LocalPool(job, 1, in_process=job.handler()) as serial_pool:
        serial = reduce_with(serial_pool, wall_world)
    parallel = reduce_with(pool, wall_world)
    assert serial.minimal == parallel.minimal == ("wall",)
    assert parallel.one_minimal and parallel.errors == 0


def test_workers_are_persistent_processes(pool: LocalPool, wall_world: World) -> None:
    pids = pool.pids
    assert len(pids) == 2 and os.getpid() not in pids
    for attempt in range(3):
        pool.call(wall_world.select(["ball"]), attempt)
    assert pool.pids == pids


def test_what_the_test_raises_comes_back_as_data(pool: LocalPool, wall_world: World) -> None:
    no_scenario = World(models=wall_world.models, name="no-scenario")
    result = pool.call(no_scenario, 0)
    assert result.run is None and result.error is not None
    assert result.error.type_name == "ScenarioError" and result.error.ddenv_error
    assert "has no scenario" in result.error.message
    failed = pool.call(wall_world, 0)
    assert failed.error.type_name == "RobotFailure" and failed.error.signature.predicate == "stuck"
    assert pool.stats.errors == 0  # the test's own errors are not pool errors


def test_in_process_pool_has_no_worker_process(wall_world: World) -> None:
    job = stuck_job()
    with LocalPool(job, 1, in_process=job.handler()) as pool:
        assert pool.in_process and pool.pids == []
        result = pool.call(wall_world, 0)
    assert result.error is not None and result.error.signature is not None
    with pytest.raises(WorkerError, match="closed"):
        pool.call(wall_world, 0)


def test_worker_errors_are_ddenv_errors() -> None:
    assert issubclass(WorkerError, DdenvError) and issubclass(WorkerStartError, WorkerError)


def test_imported_user_code_registers_custom_robots_in_the_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wall_world: World
) -> None:
    (tmp_path / "ddenv_twin_robot.py").write_text(
        "from pytest_ddenv.sim import Husky, register_robot\nregister_robot('husky_twin', Husky, replace=True)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert wall_world.scenario is not None
    twin = dataclasses.replace(wall_world, scenario=dataclasses.replace(wall_world.scenario, robot="husky_twin"))
    with LocalPool(stuck_job(), 2) as plain:
        error = plain.call(twin, 0).error
        assert error is not None and "unknown robot 'husky_twin'" in error.message
    with LocalPool(stuck_job(imports=("ddenv_twin_robot",)), 2) as pool:
        assert run_of(pool.call(twin, 0)).failure is not None


def test_a_worker_that_cannot_import_the_user_code_says_so(tmp_path: Path, wall_world: World) -> None:
    broken = tmp_path / "ddenv_broken_helpers.py"
    broken.write_text("import ddenv_module_that_does_not_exist\n")
    with LocalPool(stuck_job(imports=(str(broken),)), 2, startup_timeout=60) as pool:
        with pytest.raises(WorkerStartError, match="ddenv_module_that_does_not_exist"):
            pool.call(wall_world, 0)
        with pytest.raises(WorkerStartError):  # every later call too, without starting workers again
            pool.call(wall_world, 1)


@pytest.mark.parametrize("name", sorted(PREDICATES))
def test_every_built_in_predicate_crosses_the_process_boundary(name: str) -> None:
    """A predicate given as an object (not by name) travels pickled to the workers."""
    predicate = make_predicate(name)
    assert type(pickle.loads(pickle.dumps(predicate))) is type(predicate)
