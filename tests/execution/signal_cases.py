"""Scenarios for the signal tests of test_pool_faults.py, each run in a process of its own.

A signal test must never reach the test process (under pytest-xdist a SIGINT there aborts the whole
session, and a stray SIGALRM kills the worker), so each case runs here, in a child process that the test
started: ``python signal_cases.py CASE``. The case prints one JSON line with what it saw on stdout; faults
announce themselves on stderr ("ddenv fault injection: hang (pid N)"), which is when the test sends its
signal.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests folder: plugin/, execution/

from plugin.conftest import WALL_WORLD

from execution.conftest import reduce_with, run_of, stuck_job
from pytest_ddenv.execution import LocalPool, WorkerError
from pytest_ddenv.reduce import ReductionInterrupted
from pytest_ddenv.world import World


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


def ctrl_c_while_waiting(world: World) -> dict[str, Any]:
    """Ctrl-C while the main thread waits for a hung probe: only that worker is killed, the pool goes on."""
    result: dict[str, Any] = {"interrupted": False}
    with LocalPool(stuck_job(), 2, watchdog=None, fault_injection="hang@2") as pool:
        pool.call(world.select(["ball"]), 0)
        before = pool.pids
        try:
            pool.call(world, 0)  # simulation 2 hangs until the test's SIGINT
        except KeyboardInterrupt:
            result["interrupted"] = True
        result["live"] = len(pool.pids)
        result["killed"] = sum(gone(pid) for pid in before)
        result["goes_on"] = run_of(pool.call(world, 0)).failure is not None
        pids = pool.pids
    result["all_gone"] = all(gone(pid) for pid in pids + before)
    return result


def ctrl_c_during_parallel_reduction(world: World) -> dict[str, Any]:
    """What the driver does on Ctrl-C: the engine raises ReductionInterrupted, pool.close() frees the probe
    threads (their probes raise WorkerError), then the executor shuts down."""
    pool = LocalPool(stuck_job(), 2, watchdog=None, fault_injection="hang@3,hang@4,hang@5,hang@6,hang@7")
    executor = concurrent.futures.ThreadPoolExecutor(2)
    result: dict[str, Any] = {"reason": None}
    try:
        reduce_with(pool, world, executor=executor)
    except ReductionInterrupted as stop:
        result["reason"] = stop.reduction.incomplete_reason
    pids = pool.pids
    pool.close()
    executor.shutdown(wait=True)
    result["workers"] = len(pids)
    result["all_gone"] = all(gone(pid) for pid in pids) and not children() & set(pids)
    return result


def in_process_watchdog(world: World) -> dict[str, Any]:
    """An in-process probe that hangs is interrupted by the SIGALRM watchdog: an error, and the pool goes on."""
    job = stuck_job()
    result: dict[str, Any] = {}
    with LocalPool(job, 1, in_process=job.handler(), watchdog=3.0, fault_injection="hang@2") as pool:
        result["first"] = run_of(pool.call(world, 0)).failure is not None
        try:
            pool.call(world, 0)
            result["second"] = "returned"
        except WorkerError as error:
            result["second"] = str(error)
        result["third"] = run_of(pool.call(world, 0)).failure is not None
        result["stats"] = pool.stats.to_dict()
    result["alarm_restored"] = signal.getsignal(signal.SIGALRM) == signal.SIG_DFL
    result["timer_off"] = signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    return result


CASES = {
    "ctrl-c-while-waiting": ctrl_c_while_waiting,
    "ctrl-c-during-parallel-reduction": ctrl_c_during_parallel_reduction,
    "in-process-watchdog": in_process_watchdog,
}

if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.default_int_handler)  # even when started with SIGINT ignored
    wall = World.from_yaml(WALL_WORLD, source="wall.yaml")
    print(json.dumps(CASES[sys.argv[1]](wall)), flush=True)
