"""DaskPool on a local cluster bound to loopback: the same runs, the same minimal world."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pytest_ddenv.execution import LocalPool, PoolConfigError, make_pool
from pytest_ddenv.world import World

from .conftest import reduce_with, run_of, stuck_job

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

distributed = pytest.importorskip(
    "distributed", reason="dask.distributed is not installed (pip install 'pytest-ddenv[dask]')"
)

from pytest_ddenv.execution import DaskCluster, DaskPool


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


def test_make_pool_rejects_a_scheduler_that_is_not_there() -> None:
    with pytest.raises(PoolConfigError, match="cannot connect to the dask scheduler at tcp://127.0.0.1:9"):
        make_pool(stuck_job(), 2, "tcp://127.0.0.1:9")
