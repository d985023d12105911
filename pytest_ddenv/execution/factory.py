"""`make_pool`: the pool the command-line options ask for."""

from __future__ import annotations

from typing import Any

from pytest_ddenv.execution.base import Pool
from pytest_ddenv.execution.dask_pool import ADDRESS_SCHEMES, DaskSimulationPool
from pytest_ddenv.execution.errors import PoolConfigError
from pytest_ddenv.execution.local import SimulationPool, resolve_workers


def make_pool(workers: int | str = "auto", executor: str | None = None, **options: Any) -> Pool:
    """A pool for `--ddenv-workers` and `--ddenv-executor`.

    `executor` None (or "" / "local"): local worker processes, `workers` of them (1 = in-process).
    "dask": a local dask cluster with `workers` worker processes. "tcp://host:port" / "tls://...": a running
    dask scheduler (`workers` is then ignored: the cluster has its own). `options` go to the pool class
    (watchdog, fault_injection, ...). Raises PoolConfigError for invalid values.
    """
    count = resolve_workers(workers)
    if executor in (None, "", "local"):
        return SimulationPool(count, **options)
    if not isinstance(executor, str):
        raise PoolConfigError(f"executor must be 'dask' or a dask scheduler address, got {executor!r}")
    if executor == "dask":
        return DaskSimulationPool(None, n_workers=count, **options)
    if executor.startswith(ADDRESS_SCHEMES):
        return DaskSimulationPool(executor, **options)
    raise PoolConfigError(
        f"unknown executor {executor!r}: use 'dask' (a local dask cluster) or a dask scheduler address "
        "such as tcp://scheduler:8786"
    )
