"""Execution layer: where simulations run. Persistent local worker processes (`SimulationPool`), or a
dask.distributed cluster (`DaskSimulationPool`); `make_pool` picks one from the command-line options.

Knows the simulation layer only (no pytest, no reduction). See docs/scaling.md.
"""

from pytest_ddenv.execution.base import Pool, PoolStats
from pytest_ddenv.execution.dask_pool import DaskSimulationPool
from pytest_ddenv.execution.errors import PoolConfigError, SimulationError
from pytest_ddenv.execution.factory import make_pool
from pytest_ddenv.execution.local import SimulationPool, cpu_count, resolve_workers
from pytest_ddenv.execution.request import FAULT_ENV, Fault, PredicateLike

__all__ = [
    "FAULT_ENV",
    "DaskSimulationPool",
    "Fault",
    "Pool",
    "PoolConfigError",
    "PoolStats",
    "PredicateLike",
    "SimulationError",
    "SimulationPool",
    "cpu_count",
    "make_pool",
    "resolve_workers",
]
