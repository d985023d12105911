"""A large world crosses to a worker as bytes pickled once (`SharedWorld`), unpickled once per worker process,
and its runs stay those of the world sent."""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

import pytest

from pytest_ddenv.execution import LocalPool
from pytest_ddenv.execution.request import SHARED_WORLD_MODELS, ProbeRequest, SharedWorld
from pytest_ddenv.oracle import make_predicate
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE
from pytest_ddenv.sim import Simulator
from pytest_ddenv.world import World

from .conftest import run_of, stuck_job

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture(scope="module")
def yard() -> World:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import make_yard

        return make_yard.make_yard(SHARED_WORLD_MODELS, seed=0)
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_a_large_world_is_pickled_once_and_unpickled_once(yard: World) -> None:
    first = pickle.dumps(ProbeRequest(yard, 1))
    again = pickle.dumps(ProbeRequest(yard, 2, record=True))
    assert SharedWorld.of(yard) is SharedWorld.of(yard), "the same World object: its bytes are made once"
    one, two = pickle.loads(first), pickle.loads(again)
    assert one.world == yard and one.world.source == yard.source and one.attempt == 1
    assert two.world is one.world and (two.attempt, two.record, two.fault) == (2, True, None)
    other = yard.without([yard.names[0]])  # another world (equal content elsewhere gives the same digest)
    assert pickle.loads(pickle.dumps(ProbeRequest(other, 0))).world == other


def test_a_small_world_travels_as_itself(yard: World) -> None:
    small = yard.select(yard.names[:10])
    assert isinstance(ProbeRequest(small, 0).__reduce__()[1][0], World)
    assert pickle.loads(pickle.dumps(ProbeRequest(small, 3))).world == small


@pytest.mark.slow  # worker processes and two runs of a 1 000-object world
def test_runs_of_a_shared_world_in_a_worker_are_those_of_the_world(yard: World) -> None:
    world = yard
    with LocalPool(stuck_job(), 1, watchdog=300.0) as pool:
        runs = [run_of(pool.call(world, attempt)) for attempt in (0, 0, 3)]
    with Simulator() as simulator:
        serial = simulator.run(world, seed=0, predicates=[make_predicate("stuck", window=2.0, min_progress=0.2)])
        third = simulator.run(world, seed=3 * ATTEMPT_SEED_STRIDE,
                              predicates=[make_predicate("stuck", window=2.0, min_progress=0.2)])
    assert runs[0].same_trajectory(serial) and runs[1].same_trajectory(serial) and runs[2].same_trajectory(third)
    assert runs[0].failure == serial.failure and runs[2].failure == third.failure
