"""Execution layer: where probes run. A `Job` (the user's test, or a world's scenario) is served by
persistent local worker processes (`LocalPool`), in the calling process, on a dask.distributed cluster
(`DaskPool`) or on a Ray cluster (`RayPool`); `make_pool` picks one from the command-line options.

Knows the world model only (no pytest, no reduction): jobs are defined by the layers above. See
docs/architecture.md and docs/scaling.md.
"""

from pytest_ddenv.execution.base import WATCHDOG_ENV, Pool, PoolStats
from pytest_ddenv.execution.dask_pool import DaskCluster, DaskPool
from pytest_ddenv.execution.errors import (
    PoolConfigError,
    ProbeDeadline,
    WorkerError,
    WorkerStartError,
)
from pytest_ddenv.execution.factory import check_executor, make_cluster, make_pool
from pytest_ddenv.execution.local import (
    LocalPool,
    cpu_count,
    resolve_workers,
)
from pytest_ddenv.execution.ray_pool import RayCluster, RayPool
from pytest_ddenv.execution.request import (
    FAULT_ENV,
    Channel,
    Fault,
    Handler,
    Job,
    ProbeRequest,
    Reply,
    serve_requests,
)
from pytest_ddenv.execution.stuck import ProbeTimeout

__all__ = [
    "FAULT_ENV",
    "WATCHDOG_ENV",
    "Channel",
    "DaskCluster",
    "DaskPool",
    "Fault",
    "Handler",
    "Job",
    "LocalPool",
    "Pool",
    "PoolConfigError",
    "PoolStats",
    "ProbeDeadline",
    "ProbeRequest",
    "ProbeTimeout",
    "RayCluster",
    "RayPool",
    "Reply",
    "WorkerError",
    "WorkerStartError",
    "check_executor",
    "cpu_count",
    "make_cluster",
    "make_pool",
    "resolve_workers",
    "serve_requests",
]
