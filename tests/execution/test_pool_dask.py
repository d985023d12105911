"""DaskSimulationPool on a local cluster bound to loopback: same Runs, same minimal world."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pytest_ddenv.execution import PoolConfigError, SimulationPool, make_pool
from pytest_ddenv.world import World

from .conftest import STUCK, reduce_with

distributed = pytest.importorskip(
    "distributed", reason="dask.distributed is not installed (pip install 'pytest-ddenv[dask]')"
)

from pytest_ddenv.execution import DaskSimulationPool


@pytest.fixture(scope="module")
def dask_pool() -> Iterator[DaskSimulationPool]:
    with DaskSimulationPool(None, n_workers=2, watchdog=120.0) as pool:
        yield pool


def test_the_local_cluster_listens_on_loopback_only(dask_pool: DaskSimulationPool) -> None:
    assert dask_pool.address.startswith("tcp://127.0.0.1:")
    assert dask_pool.size == 2
    assert all(address.startswith("tcp://127.0.0.1:") for address in dask_pool.client.nthreads())


def test_dask_runs_equal_local_runs(dask_pool: DaskSimulationPool, wall_world: World) -> None:
    with SimulationPool(1) as local:
        for world in (wall_world, wall_world.without(["wall"])):
            remote_run = dask_pool.simulate(world, seed=3, predicates=STUCK)
            local_run = local.simulate(world, seed=3, predicates=STUCK)
            assert remote_run.same_trajectory(local_run) and remote_run.failure == local_run.failure


def test_a_reduction_on_dask_finds_the_same_minimal_world(dask_pool: DaskSimulationPool, wall_world: World) -> None:
    reduction = reduce_with(dask_pool.simulate, wall_world, workers=dask_pool.size)
    assert reduction.minimal == ("wall",) and reduction.one_minimal and reduction.errors == 0
    assert dask_pool.stats.probes >= reduction.probes


def test_make_pool_rejects_a_scheduler_that_is_not_there() -> None:
    with pytest.raises(PoolConfigError, match="cannot connect to the dask scheduler at tcp://127.0.0.1:9"):
        make_pool(2, "tcp://127.0.0.1:9", connect_timeout=2.0)
