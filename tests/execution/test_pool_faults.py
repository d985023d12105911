"""Faults: a worker that dies is replaced and its probe retried once; a hung one is killed by the watchdog;
close() and Ctrl-C leave no process behind."""

from __future__ import annotations

import concurrent.futures
import os
import signal
import threading
import time
from pathlib import Path

import pytest

from pytest_ddenv.execution import Fault, LocalPool, WorkerError
from pytest_ddenv.execution.request import FaultKind
from pytest_ddenv.reduce import ReductionInterrupted
from pytest_ddenv.world import World

from .conftest import reduce_with, run_of, stuck_job


def gone(pid: int) -> bool:
    """True when `pid` no longer exists (a zombie still exists: it was not reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def children() -> set[int]:
    """Process ids of this process's children, zombies included (Linux /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == os.getpid():
                found.add(int(entry.name))
    return found


@pytest.mark.parametrize("kind", ["crash", "kill"])
def test_a_worker_crash_is_retried_and_the_reduction_still_finds_the_wall(kind: FaultKind, wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, fault_injection=[Fault(kind, 3), Fault(kind, 6)]) as pool:
        reduction = reduce_with(pool, wall_world)
        stats = pool.stats
    assert reduction.minimal == ("wall",) and reduction.errors == 0
    assert stats.crashes == 2 and stats.retries == 2 and stats.restarts == 2 and stats.errors == 0


def test_a_simulation_whose_worker_dies_twice_raises(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, fault_injection="exit@1x2") as pool:
        with pytest.raises(WorkerError, match=r"failed twice.*exited with status 70"):
            pool.call(wall_world, 0)
        assert run_of(pool.call(wall_world, 0)).failure is not None  # the pool goes on
        stats = pool.stats
    assert (stats.crashes, stats.retries, stats.errors) == (2, 1, 1)


def test_a_hung_worker_is_killed_by_the_watchdog_and_the_reduction_goes_on(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, watchdog=5.0, fault_injection="hang@4") as pool:
        started = time.monotonic()
        reduction = reduce_with(pool, wall_world, deflake=1)
        stats = pool.stats
    assert reduction.minimal == ("wall",)
    assert stats.timeouts == 1 and stats.errors == 1
    # the hung simulation may belong to a speculative probe the parallel engine abandoned (not counted)
    assert reduction.errors <= 1
    assert time.monotonic() - started < 45


def test_the_automatic_watchdog_follows_the_slowest_simulation(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, watchdog_floor=1.0, watchdog_factor=10.0) as pool:
        assert pool.watchdog_seconds() == 1.0
        run = run_of(pool.call(wall_world, 0))
        assert pool.watchdog_seconds() == pytest.approx(max(1.0, 10 * pool.stats.slowest))
        assert pool.stats.slowest >= run.wall_time


def test_close_stops_busy_workers_promptly_and_reaps_them(wall_world: World) -> None:
    pool = LocalPool(stuck_job(), 2, fault_injection="hang@1")
    outcome: list[BaseException] = []

    def blocked() -> None:
        try:
            pool.call(wall_world, 0)
        except BaseException as error:  # noqa: BLE001
            outcome.append(error)

    thread = threading.Thread(target=blocked)
    thread.start()
    pool.call(wall_world.select(["ball"]), 0)  # both workers are up
    pids = pool.pids
    started = time.monotonic()
    pool.close()
    thread.join(10)
    assert time.monotonic() - started < 5
    assert not thread.is_alive() and isinstance(outcome[0], WorkerError) and "closed" in str(outcome[0])
    assert len(pids) == 2 and all(gone(pid) for pid in pids)
    assert not children() & set(pids)


@pytest.mark.usefixtures("ctrl_c_raises")
def test_ctrl_c_while_waiting_kills_only_that_worker_and_the_pool_goes_on(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, fault_injection="hang@2") as pool:
        pool.call(wall_world.select(["ball"]), 0)
        before = pool.pids
        timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        started = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            pool.call(wall_world, 0)  # simulation 2 hangs
        assert time.monotonic() - started < 5
        timer.join()
        assert len(pool.pids) == 1 and sum(gone(pid) for pid in before) == 1  # the hung worker was killed
        assert run_of(pool.call(wall_world, 0)).failure is not None
        pids = pool.pids
    assert all(gone(pid) for pid in pids + before)


def test_workers_ignore_sigint_so_ctrl_c_in_a_terminal_does_not_kill_them(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2) as pool:
        pool.call(wall_world.select(["ball"]), 0)
        pids = pool.pids
        for pid in pids:
            os.kill(pid, signal.SIGINT)
        time.sleep(0.3)
        assert run_of(pool.call(wall_world, 0)).failure is not None
        assert pool.stats.crashes == 0


@pytest.mark.usefixtures("ctrl_c_raises")
def test_ctrl_c_during_a_parallel_reduction_stops_hung_workers_promptly(wall_world: World) -> None:
    """What the driver does on Ctrl-C: the engine raises ReductionInterrupted, then pool.close() frees the
    probe threads (their probes raise WorkerError), then the executor shuts down."""
    pool = LocalPool(stuck_job(), 2, fault_injection="hang@3,hang@4,hang@5,hang@6,hang@7")
    executor = concurrent.futures.ThreadPoolExecutor(2)
    timer = threading.Timer(2.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(ReductionInterrupted) as raised:
        reduce_with(pool, wall_world, executor=executor)
    timer.join()
    pids = pool.pids
    started = time.monotonic()
    pool.close()
    executor.shutdown(wait=True)
    assert time.monotonic() - started < 5
    assert raised.value.reduction.incomplete_reason == "interrupted"
    assert len(pids) == 2 and all(gone(pid) for pid in pids) and not children() & set(pids)
