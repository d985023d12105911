"""A tiny world with a wall across the robot's path, and a bare reduction driven through a pool."""

from __future__ import annotations

import concurrent.futures
import signal
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import pytest
from plugin.conftest import WALL_WORLD  # the same small world as the plugin tests

from pytest_ddenv.markers import PredicateSpec
from pytest_ddenv.oracle import classify
from pytest_ddenv.probe import trace_of
from pytest_ddenv.reduce import Observation, Outcome, Reduction, reduce
from pytest_ddenv.robot_world import ATTEMPT_SEED_STRIDE
from pytest_ddenv.world import World

STUCK = (PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),)
SimulateFn = Callable[..., Any]


@pytest.fixture
def ctrl_c_raises() -> Iterator[None]:
    """Ctrl-C (SIGINT) raises KeyboardInterrupt in this process, even where it was started with SIGINT
    ignored (a background job: CI runners, nohup)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.fixture(scope="session")
def wall_world() -> World:
    return World.from_yaml(WALL_WORLD, source="wall.yaml")


def reduce_with(
    simulate: SimulateFn,
    world: World,
    *,
    workers: int = 2,
    deflake: int = 0,
    predicates: Sequence[PredicateSpec] = STUCK,
    seed: int = 0,
    executor: concurrent.futures.Executor | None = None,
) -> Reduction:
    """Reduce `world` with probes that call `simulate` (a pool's), `workers` probes in flight at once
    (on `executor` if given: the caller shuts it down)."""
    reference = simulate(world, seed=seed, predicates=predicates)
    assert reference.failure is not None, "the test world must fail"

    def probe(candidate: tuple[str, ...], attempt: int) -> Observation:
        run = simulate(world.select(candidate), seed=seed + attempt * ATTEMPT_SEED_STRIDE, predicates=predicates)
        outcome = classify(run, reference.failure, 0.5)
        return Observation(outcome, trace=trace_of(run) if outcome is Outcome.FAIL else None, seed=run.seed,
                           sim_time=run.sim_time)

    own = executor is None and workers > 1
    if own:
        executor = concurrent.futures.ThreadPoolExecutor(workers)
    try:
        return reduce(world.names, probe, geometry=world, reference=trace_of(reference), deflake=deflake,
                      seed=seed, failure_rate_runs=0, executor=executor)
    finally:
        if own and executor is not None:
            executor.shutdown(wait=True)
