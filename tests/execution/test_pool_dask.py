"""DaskPool on a local cluster bound to loopback: the same runs, the same minimal world; the test runs in the
main thread of a probe process of each dask worker, which the watchdog can kill."""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pytest_ddenv.execution import (
    Fault,
    LocalPool,
    PoolConfigError,
    ProbeDeadline,
    WorkerError,
    make_pool,
)
from pytest_ddenv.world import World

from .conftest import HANG, UserCodeJob, alive, gone, reduce_with, run_of, stuck_job

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

distributed = pytest.importorskip(
    "distributed", reason="dask.distributed is not installed (pip install 'pytest-ddenv[dask]')"
)

from pytest_ddenv.execution import DaskCluster, DaskPool  # noqa: E402 - after the importorskip


@pytest.fixture(scope="module")
def cluster() -> Iterator[DaskCluster]:
    with DaskCluster(None, n_workers=2) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def dask_pool(cluster: DaskCluster) -> Iterator[DaskPool]:
    with DaskPool(stuck_job(), cluster, watchdog=120.0) as pool:
        yield pool


def test_the_local_cluster_listens_on_loopback_only(cluster: DaskCluster, dask_pool: DaskPool) -> None:
    assert cluster.address.startswith("tcp://127.0.0.1:")
    assert dask_pool.size == 2
    assert all(address.startswith("tcp://127.0.0.1:") for address in cluster.client.nthreads())


def test_dask_runs_equal_local_runs(dask_pool: DaskPool, wall_world: World) -> None:
    job = stuck_job()
    with LocalPool(job, 1, in_process=job.handler()) as local:
        for world in (wall_world, wall_world.without(["wall"])):
            remote_run = run_of(dask_pool.call(world, 3))
            local_run = run_of(local.call(world, 3))
            assert remote_run.same_trajectory(local_run) and remote_run.failure == local_run.failure


def test_a_reduction_on_dask_finds_the_same_minimal_world(dask_pool: DaskPool, wall_world: World) -> None:
    reduction = reduce_with(dask_pool, wall_world)
    assert reduction.minimal == ("wall",) and reduction.one_minimal and reduction.errors == 0
    assert dask_pool.stats.probes >= reduction.probes


def test_the_dask_workers_are_daemonic_and_the_test_runs_in_the_main_thread_of_a_probe_process(
        cluster: DaskCluster, wall_world: World, tmp_path: Path) -> None:
    daemonic = cluster.client.run(lambda: multiprocessing.current_process().daemon)
    dask_pids = set(cluster.client.run(os.getpid).values())
    assert daemonic and all(daemonic.values())  # dask's default: probe processes start all the same
    with DaskPool(UserCodeJob(str(tmp_path / "pid")), cluster, watchdog=60.0) as pool:
        results = [pool.call(wall_world, attempt) for attempt in range(4)]
    assert all(result["models"] == len(wall_world) for result in results)
    assert not {result["pid"] for result in results} & dask_pids  # not in the dask worker processes
    assert pool.stats.probes == 4 and pool.stats.errors == 0 and pool.stats.restarts == 0


def test_a_hung_probe_is_killed_by_the_watchdog_and_the_next_probe_runs(
        cluster: DaskCluster, wall_world: World, tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    with DaskPool(UserCodeJob(str(pid_file)), cluster, watchdog=3.0) as pool:
        before = pool.call(wall_world, 0)
        started = time.monotonic()
        with pytest.raises(WorkerError, match=r"ran past the 3 s watchdog; its probe process \(dask worker .* "
                                              r"pid \d+, probe process pid \d+\) was killed") as raised:
            pool.call(wall_world, HANG)
        assert not isinstance(raised.value, ProbeDeadline)
        assert 3.0 <= time.monotonic() - started < 20.0
        assert gone(int(pid_file.read_text()))
        after = [pool.call(wall_world, attempt) for attempt in range(1, 4)]
        stats = pool.stats
    assert before["models"] == len(wall_world) and all(result["models"] == len(wall_world) for result in after)
    assert stats.timeouts == 1 and stats.errors == 1 and stats.probes == 4 and stats.cancelled == 0


def test_a_probe_past_its_deadline_is_killed_and_reported_as_a_deadline(
        cluster: DaskCluster, wall_world: World, tmp_path: Path) -> None:
    pid_file = tmp_path / "pid"
    with DaskPool(UserCodeJob(str(pid_file)), cluster, watchdog=60.0) as pool:
        pool.call(wall_world, 0)
        with pytest.raises(ProbeDeadline, match="stopped at the reduction's deadline; its probe process"):
            pool.call(wall_world, HANG, timeout=2.0)
        assert gone(int(pid_file.read_text()))
        assert pool.call(wall_world, 1)["models"] == len(wall_world)
        stats = pool.stats
    assert stats.cancelled == 1 and stats.timeouts == 0 and stats.errors == 0


def test_a_probe_process_that_crashes_is_replaced_and_its_probe_retried(
        cluster: DaskCluster, wall_world: World, tmp_path: Path) -> None:
    job = UserCodeJob(str(tmp_path / "pid"))
    with DaskPool(job, cluster, watchdog=60.0, fault_injection=[Fault("crash", 2)]) as pool:
        pool.call(wall_world, 0)
        second = pool.call(wall_world, 1)  # crashes once, then runs on a fresh probe process
        stats = pool.stats
    assert second["models"] == len(wall_world) and stats.errors == 0
    assert stats.crashes == 1 and stats.retries == 1 and stats.restarts == 1 and stats.simulations == 3
    with DaskPool(job, cluster, watchdog=60.0, fault_injection=[Fault("kill", 1, tries=2)]) as pool:
        with pytest.raises(WorkerError, match="failed twice: its probe process died each time"):
            pool.call(wall_world, 0)
        assert pool.call(wall_world, 1)["models"] == len(wall_world)
        assert pool.stats.crashes == 2 and pool.stats.errors == 1


def hosted_jobs() -> dict[str, int]:
    """On a dask worker: how many probe processes each job it hosts has, by job key."""
    from pytest_ddenv.execution import dask_host

    return {key: len(hosted._live) for key, hosted in dask_host.hosted_jobs().jobs.items()}


def test_a_dask_worker_keeps_the_probe_processes_of_its_most_recent_jobs_only(
        cluster: DaskCluster, wall_world: World, tmp_path: Path) -> None:
    from pytest_ddenv.execution.dask_host import JOBS_KEPT

    pids, keys = [], set()
    for index in range(2 * JOBS_KEPT + 1):  # on 2 dask workers: at least one evicts a job
        job = UserCodeJob(str(tmp_path / f"pid-{index}"))
        keys.add(job.key)
        with DaskPool(job, cluster, watchdog=60.0) as pool:
            pids.append(pool.call(wall_world, 0)["pid"])
    kept = cluster.client.run(hosted_jobs)
    assert all(len(jobs) <= JOBS_KEPT and all(count <= 1 for count in jobs.values()) for jobs in kept.values())
    # The workers may still host jobs of earlier tests (the cluster is the module's): count this test's.
    ours = sum(count for jobs in kept.values() for key, count in jobs.items() if key in keys)
    assert ours < len(pids), "some of this test's jobs were evicted"
    deadline = time.monotonic() + 10.0  # evicted jobs stop in the background
    while sum(map(alive, pids)) != ours and time.monotonic() < deadline:
        time.sleep(0.05)
    assert sum(map(alive, pids)) == ours


def test_make_pool_rejects_a_scheduler_that_is_not_there() -> None:
    with pytest.raises(PoolConfigError, match=r"cannot connect to the dask scheduler at tcp://127\.0\.0\.1:9"):
        make_pool(stuck_job(), 2, "tcp://127.0.0.1:9")
