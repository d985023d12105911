"""Faults: a worker that dies is replaced and its probe retried once; a hung one is killed by the watchdog
(in-process: interrupted by SIGALRM); close() and Ctrl-C leave no process behind.

No wall-clock assertion (DESIGN.md section 10): the tests assert outcomes and that processes are gone; time
limits are only generous hang guards. Signal tests run their scenario in a child process (signal_cases.py)
and signal only that child, never the test process (under pytest-xdist a SIGINT there aborts the session).
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.execution import Fault, LocalPool, ProbeDeadline, WorkerError
from pytest_ddenv.execution.base import DEFAULT_RUN_CAP, FIRST_RUN_MARGIN
from pytest_ddenv.execution.request import FaultKind
from pytest_ddenv.world import World

from .conftest import reduce_with, run_of, stuck_job
from .signal_cases import children, gone

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

HANG_GUARD = 120.0
"""Seconds after which a test that should have ended long before gives up (a guard, not a speed check)."""
CASES = Path(__file__).with_name("signal_cases.py")


def run_case(case: str, *, interrupt_on: str | None = None) -> dict[str, Any]:
    """Run a case of signal_cases.py in a child process; with `interrupt_on`, send it SIGINT once that text
    appears on its stderr (a fault announcing itself). Returns the JSON the case printed."""
    process = subprocess.Popen([sys.executable, str(CASES), case], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)  # its own group: no signal leaks either way
    lines: queue.Queue[str] = queue.Queue()
    errors: list[str] = []

    def read_stderr() -> None:
        assert process.stderr is not None
        for line in process.stderr:
            errors.append(line)
            lines.put(line)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        if interrupt_on is not None:
            deadline = time.monotonic() + HANG_GUARD
            while time.monotonic() < deadline:
                try:
                    if interrupt_on in lines.get(timeout=1.0):
                        break
                except queue.Empty:
                    assert process.poll() is None, "".join(errors)
            else:
                pytest.fail(f"{interrupt_on!r} never appeared:\n{''.join(errors)}")
            process.send_signal(signal.SIGINT)
        output, _ = process.communicate(timeout=HANG_GUARD)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    reader.join(5)
    assert process.returncode == 0, "".join(errors)
    return json.loads(output.strip().splitlines()[-1])


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
    with LocalPool(stuck_job(), 2, watchdog=10.0, fault_injection="hang@4") as pool:
        reduction = reduce_with(pool, wall_world, deflake=1)
        stats = pool.stats
    assert reduction.minimal == ("wall",)
    assert stats.timeouts == 1 and stats.errors == 1
    # the hung simulation may belong to a speculative probe the parallel engine abandoned (not counted)
    assert reduction.errors <= 1


def test_the_automatic_watchdog_follows_the_original_run_and_the_slowest_simulation(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2, watchdog_floor=1.0, watchdog_factor=10.0) as pool:
        # no run timed yet: the run's own wall-clock cap + a margin, never the floor (issue 33)
        assert pool.watchdog_seconds() == DEFAULT_RUN_CAP + FIRST_RUN_MARGIN  # ScenarioJob: a 300 s cap
        pool.expect(0.5)  # the original run took 0.5 s
        assert pool.watchdog_seconds() == 5.0
        run = run_of(pool.call(wall_world, 0))
        assert pool.watchdog_seconds() == pytest.approx(max(5.0, 10 * pool.stats.slowest))
        assert pool.stats.slowest >= run.wall_time
        assert pool.stats.simulations == 1 and pool.stats.cpu_seconds > 0


def test_the_watchdog_can_be_set_by_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    from pytest_ddenv.execution import PoolConfigError

    job = stuck_job()
    monkeypatch.setenv("DDENV_PROBE_TIMEOUT", "7.5")
    assert LocalPool(job, 1, in_process=job.handler()).watchdog_seconds() == 7.5
    monkeypatch.setenv("DDENV_PROBE_TIMEOUT", "none")
    assert LocalPool(job, 1, in_process=job.handler()).watchdog_seconds() is None
    assert LocalPool(job, 1, in_process=job.handler(), watchdog=3).watchdog_seconds() == 3.0, "explicit wins"
    monkeypatch.setenv("DDENV_PROBE_TIMEOUT", "soon")
    with pytest.raises(PoolConfigError, match=r"\$DDENV_PROBE_TIMEOUT: expected a number of seconds > 0, 'auto' or 'none', got 'soon'"):
        LocalPool(job, 1, in_process=job.handler())


def test_a_probe_past_its_callers_deadline_is_stopped_and_not_an_error(wall_world: World) -> None:
    with LocalPool(stuck_job(), 1, watchdog=None, fault_injection="hang@2") as pool:
        assert run_of(pool.call(wall_world, 0, timeout=HANG_GUARD)).failure is not None
        with pytest.raises(ProbeDeadline, match="stopped at the reduction's deadline"):
            pool.call(wall_world, 0, timeout=1.0)
        assert run_of(pool.call(wall_world, 0)).failure is not None  # a fresh worker
        stats = pool.stats
    assert stats.cancelled == 1 and stats.errors == 0 and stats.timeouts == 0


def test_a_hung_in_process_probe_is_interrupted_and_the_pool_goes_on() -> None:
    seen = run_case("in-process-watchdog")
    assert seen["first"] and seen["third"]
    assert "ran past the 3 s watchdog in this process; it was interrupted" in seen["second"]
    assert seen["stats"]["timeouts"] == 1 and seen["stats"]["errors"] == 1 and seen["stats"]["simulations"] == 3
    assert seen["alarm_restored"] and seen["timer_off"]


def test_close_stops_busy_workers_and_reaps_them(wall_world: World) -> None:
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
    pool.close()
    thread.join(HANG_GUARD)
    assert not thread.is_alive() and isinstance(outcome[0], WorkerError) and "closed" in str(outcome[0])
    assert len(pids) == 2 and all(gone(pid) for pid in pids)
    assert not children() & set(pids)


def test_ctrl_c_while_waiting_kills_only_that_worker_and_the_pool_goes_on() -> None:
    seen = run_case("ctrl-c-while-waiting", interrupt_on="ddenv fault injection: hang")
    assert seen == {"interrupted": True, "live": 1, "killed": 1, "goes_on": True, "all_gone": True}


def test_workers_ignore_sigint_so_ctrl_c_in_a_terminal_does_not_kill_them(wall_world: World) -> None:
    with LocalPool(stuck_job(), 2) as pool:
        pool.call(wall_world.select(["ball"]), 0)
        pids = pool.pids
        for pid in pids:  # processes this test started (the pool's workers), never the test process
            os.kill(pid, signal.SIGINT)
        time.sleep(0.3)
        assert run_of(pool.call(wall_world, 0)).failure is not None
        assert pool.stats.crashes == 0


def test_ctrl_c_during_a_parallel_reduction_stops_hung_workers() -> None:
    seen = run_case("ctrl-c-during-parallel-reduction", interrupt_on="ddenv fault injection: hang")
    assert seen == {"reason": "interrupted", "workers": 2, "all_gone": True}
