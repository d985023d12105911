"""A tiny world with a wall across the robot's path, its scenario as a probe job, and a bare reduction
driven through a pool."""

from __future__ import annotations

import concurrent.futures
from collections.abc import Sequence
from typing import Any

import pytest
from plugin.conftest import WALL_WORLD  # the same small world as the plugin tests

from pytest_ddenv.execution import Pool
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.scenario.probe import FailureReference, ProbeResult, make_probe, trace_of
from pytest_ddenv.reduce import Reduction, reduce
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.world import World

STUCK = (PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),)


@pytest.fixture(scope="session")
def wall_world() -> World:
    return World.from_yaml(WALL_WORLD, source="wall.yaml")


def stuck_job(**options: Any) -> ScenarioJob:
    """The wall world's scenario with the `stuck` predicate (2 s window), as a probe job."""
    return ScenarioJob(STUCK, **options)


def run_of(result: Any) -> Any:
    assert isinstance(result, ProbeResult) and result.run is not None
    return result.run


def reduce_with(
    pool: Pool,
    world: World,
    *,
    deflake: int = 0,
    predicates: Sequence[PredicateSpec] = STUCK,
    executor: concurrent.futures.Executor | None = None,
) -> Reduction:
    """Reduce `world` with probes on `pool`, `pool.size` probes in flight at once (on `executor` if given:
    the caller shuts it down)."""
    del predicates  # the pool's job has them
    original = pool.call(world, 0)
    assert original.error is not None and original.error.signature is not None, "the test world must fail"
    probe = make_probe(world, pool.call, FailureReference.of(original.error), tolerance=0.5)
    own = executor is None and pool.size > 1
    if own:
        executor = concurrent.futures.ThreadPoolExecutor(pool.size)
    try:
        return reduce(world.names, probe, geometry=world, reference=trace_of(original.run), deflake=deflake,
                      seed=0, failure_rate_runs=0, executor=executor, workers=pool.size)
    finally:
        if own and executor is not None:
            executor.shutdown(wait=True)
