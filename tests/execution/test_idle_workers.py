"""The default number of workers is what the machine has idle (issue 33): real CPU-bound processes beside the
test, the count measured from /proc/stat; an explicit count stays as given."""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

from burners import every_core_busy

from pytest_ddenv.execution import LocalPool, cpu_count, make_pool
from pytest_ddenv.execution.factory import _idle_share, _ticks, default_workers, idle_cores, start_forkserver

from .conftest import stuck_job


def test_idle_cores_is_at_least_one_and_at_most_the_cores() -> None:
    assert 1 <= idle_cores() <= cpu_count()


def test_a_busy_machine_gets_one_worker_in_this_process_and_an_explicit_count_stays() -> None:
    job = stuck_job()
    with every_core_busy():
        assert idle_cores() == 1
        assert default_workers("auto") == 1
        with make_pool(job, "auto", in_process=job.handler()) as pool:  # the plugin's default
            assert isinstance(pool, LocalPool) and pool.in_process and pool.size == 1
        assert default_workers(3) == 3 and default_workers("2") == 2  # the user's --ddenv-workers N


def test_a_process_ticks_are_its_cpu_seconds_and_a_process_gone_has_none() -> None:
    started = time.process_time()
    while time.process_time() - started < 0.3:  # some CPU time of this process's own
        sum(i * i for i in range(1_000))
    (ticks,) = _ticks([os.getpid()])
    used = os.times()
    assert abs(ticks / os.sysconf("SC_CLK_TCK") - (used.user + used.system)) < 0.05
    ended = subprocess.Popen(["true"])
    ended.wait()  # gone and waited for: no /proc entry
    assert _ticks([ended.pid]) == [0]


def test_our_own_busy_processes_count_as_idle_cores() -> None:
    """The session's background media are 'ours': the cores they use are idle to a reduction about to start."""
    with every_core_busy() as ours:
        others_only, with_ours = _idle_share(0.3), _idle_share(0.3, ours)
    assert with_ours > others_only + 0.1, (others_only, with_ours)  # ours hold a share of the cores, even loaded


def _parent_of(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[1])


def test_workers_are_forked_from_the_forkserver_started_ahead() -> None:
    import multiprocessing.forkserver

    start_forkserver()
    server = multiprocessing.forkserver._forkserver._forkserver_pid  # type: ignore[attr-defined]
    start_forkserver()  # the second call finds it running
    assert server is not None and multiprocessing.forkserver._forkserver._forkserver_pid == server  # type: ignore[attr-defined]
    with make_pool(stuck_job(), 2) as pool:
        assert pool.size == 2 and not pool.in_process
        assert [_parent_of(pid) for pid in pool.pids] == [server, server]
