"""A tiny world with a wall across the robot's path, its scenario as a probe job, a job that does what user
code may do (`UserCodeJob`), and a bare reduction driven through a pool."""

from __future__ import annotations

import concurrent.futures
import os
import signal
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from plugin.conftest import WALL_WORLD  # the same small world as the plugin tests

from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.execution import Channel, Pool, serve_requests
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.reduce import Reduction, reduce
from pytest_ddenv.scenario.probe import FailureReference, ProbeResult, make_probe, trace_of
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


HANG = 99
"""The attempt number on which `UserCodeJob` hangs."""


@dataclass(frozen=True)
class UserCodeJob:
    """A job whose probes do what user code may do: need the main thread (signal handlers) and, on attempt
    `HANG`, hang (after writing their pid to `pid_file`)."""

    pid_file: str
    key: str = field(default_factory=lambda: uuid.uuid4().hex)

    @property
    def label(self) -> str:
        return "user-code job"

    def serve(self, channel: Channel) -> None:
        serve_requests(channel, self.probe)

    def probe(self, world: World, attempt: int) -> dict[str, Any]:
        assert threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGUSR1, lambda signum, frame: None)  # ValueError off the main thread
        signal.signal(signal.SIGUSR1, previous)
        if attempt == HANG:
            Path(self.pid_file).write_text(str(os.getpid()))
            time.sleep(3600)
        return {"pid": os.getpid(), "parent": os.getppid(), "models": len(world)}


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def gone(pid: int, within: float = 10.0) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False
