"""Probes on a dask.distributed cluster (optional extra `dask`): `DaskCluster` is the connection (a session
may share one), `DaskPool` runs the probes of one `Job` on it with the `Pool` API.

A probe is a dask task, `dask_host.run_probe_task` (imported by name on the workers: pytest-ddenv must be
installed there): each dask worker process runs the job's `serve` in the main thread of probe processes of
its own, started like `LocalPool`'s workers on the first probe of that job and kept for the next ones, so
the test module is imported once per probe process, not per probe. The watchdog runs there too: a probe
process past it is killed, one that dies is replaced and its probe retried once. ``address=None`` or
``"dask"`` starts a LocalCluster of worker processes bound to 127.0.0.1; ``tcp://host:port`` (or ``tls://``)
connects to a running scheduler. Dask reschedules the tasks of a worker process that dies; after
`distributed.scheduler.allowed-failures` deaths it gives up (KilledWorker): `WorkerError`.
"""

from __future__ import annotations

import contextlib
import threading
import time
import uuid
from collections.abc import Sequence
from typing import Any, Self

from pytest_ddenv.execution.base import (
    DEFAULT,
    DEFAULT_WATCHDOG_FACTOR,
    DEFAULT_WATCHDOG_FLOOR,
    ClusterPoolBase,
    limit_of,
    world_size,
)
from pytest_ddenv.execution.dask_host import JOBS_KEPT, TaskReply, run_probe_task, worker_versions
from pytest_ddenv.execution.errors import (
    PoolConfigError,
    ProbeDeadline,
    WorkerError,
    WorkerStartError,
)
from pytest_ddenv.execution.local import STARTUP_TIMEOUT
from pytest_ddenv.execution.probe_host import finish, version_problem
from pytest_ddenv.execution.request import (
    Fault,
    Job,
    ProbeRequest,
    describe_request,
    fault_for,
    parse_faults,
)
from pytest_ddenv.world.model import World

ADDRESS_SCHEMES = ("tcp://", "tls://")
CONNECT_TIMEOUT = 30.0
DEADLINE_GRACE = 2.0
"""Seconds past a probe's deadline the pool waits for the dask worker to report that it stopped the probe,
before it cancels the task itself."""
BACKSTOP_GRACE = 30.0
"""Seconds past its watchdog (and the time a probe process may take to start) the pool waits for a task the
dask worker does not report on (a cluster that lost it, a long queue) before it cancels it."""
__all__ = ["DEADLINE_GRACE", "JOBS_KEPT", "DaskCluster", "DaskPool", "run_probe_task", "worker_versions"]


# -- where pytest runs ---------------------------------------------------------------------------------


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise PoolConfigError(
            "the dask executor needs dask.distributed: pip install 'pytest-ddenv[dask]' (or 'dask[distributed]')"
        ) from None
    return distributed


class DaskCluster:
    """A connection to a dask cluster: a LocalCluster of `n_workers` single-threaded worker processes on
    127.0.0.1 (`address` None or "dask"), or a running scheduler at tcp://host:port. Checks that every
    worker has the same pytest-ddenv, pybullet and numpy (runs are bit-identical only then)."""

    def __init__(self, address: str | None = None, *, n_workers: int | None = None,
                 connect_timeout: float = CONNECT_TIMEOUT, check_versions: bool = True) -> None:
        from pytest_ddenv.execution.local import cpu_count, resolve_workers

        distributed = _import_distributed()
        self._cluster: Any = None
        local = address in (None, "dask")
        if local:
            count = cpu_count() if n_workers is None else resolve_workers(n_workers)
            self._cluster = distributed.LocalCluster(
                n_workers=count, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=None, silence_logs=40,
            )
            self.address = str(self._cluster.scheduler_address)
        else:
            if not isinstance(address, str) or not address.startswith(ADDRESS_SCHEMES):
                raise PoolConfigError(
                    f"dask executor address must be 'dask' (a local cluster) or a scheduler address like "
                    f"tcp://host:8786, got {address!r}"
                )
            self.address = address
        try:
            self.client: Any = distributed.Client(self._cluster or address, timeout=connect_timeout,
                                                  set_as_default=False)
        except (OSError, TimeoutError) as error:
            self._close_cluster()
            raise PoolConfigError(f"cannot connect to the dask scheduler at {address}: {error}") from error
        try:
            if not local:
                self.client.wait_for_workers(1, timeout=connect_timeout)
            if check_versions:
                self._check_versions()
        except BaseException:
            self.close()
            raise
        self.closed = False

    @property
    def threads(self) -> int:
        """Probes the cluster can run at once."""
        return max(1, int(sum(self.client.nthreads().values())))

    def close(self) -> None:
        self.closed = True
        client = getattr(self, "client", None)
        if client is not None:
            with contextlib.suppress(Exception):  # best effort at shutdown
                client.close(timeout=10)
        self._close_cluster()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _close_cluster(self) -> None:
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close(timeout=10)
            self._cluster = None

    def _check_versions(self) -> None:
        try:
            remote: dict[str, dict[str, str]] = self.client.run(worker_versions)
        except Exception as error:  # typically ModuleNotFoundError on the worker
            raise PoolConfigError(
                f"the dask workers at {self.address} cannot run pytest-ddenv ({type(error).__name__}: {error}); "
                "install the same pytest-ddenv, pybullet and numpy on every worker"
            ) from error
        for worker, versions in sorted(remote.items()):
            problem = version_problem(f"dask worker {worker}", versions)
            if problem is not None:
                raise PoolConfigError(problem)


class DaskPool(ClusterPoolBase):
    """The probes of `job` on a `DaskCluster` (the `Pool` API).

    `watchdog` as for `LocalPool`: the dask worker kills the probe process of a probe past it (the time the
    probe waited in dask's queue and its probe process took to start is not counted), `WorkerError`; a probe
    past its caller's `timeout` is stopped the same way, `ProbeDeadline`. A probe process that dies is
    replaced and its probe retried once (`WorkerError` if it dies again); a dask worker process that dies is
    dask's business (it reschedules the task, then gives up: `WorkerError`). `fault_injection` as for
    `LocalPool` (the faults hit probe processes, never the dask workers). `owns_cluster`: close the cluster
    with the pool. `close()` cancels the probes still waiting for their results, so that the threads
    waiting on them return at once (`WorkerError`).
    """

    def __init__(
        self,
        job: Job,
        cluster: DaskCluster,
        *,
        watchdog: float | str | None = DEFAULT,
        watchdog_floor: float = DEFAULT_WATCHDOG_FLOOR,
        watchdog_factor: float = DEFAULT_WATCHDOG_FACTOR,
        fault_injection: str | Sequence[Fault] | None = None,
        owns_cluster: bool = False,
    ) -> None:
        self.job = job
        self.cluster = cluster
        self._owns_cluster = owns_cluster
        super().__init__(cluster.threads, watchdog, watchdog_floor, watchdog_factor)
        self._faults = parse_faults(fault_injection)
        self._sequence = 0
        self._lock = threading.Lock()
        self._closed = False
        self._start_error: WorkerStartError | None = None
        self._pending: set[Any] = set()
        self.notes: list[str] = []
        """Nothing to say so far: a dask pool changes nothing on its own (`Pool.notes`)."""

    def call(self, world: World, attempt: int, *, timeout: float | None = None, record: bool = False) -> Any:
        """Like `LocalPool.call`, on the cluster."""
        if self._closed or self.cluster.closed:
            raise WorkerError("the dask pool is closed")
        if self._start_error is not None:
            raise self._start_error
        with self._lock:
            self._sequence += 1
            sequence = self._sequence
        request = ProbeRequest(world, int(attempt), fault_for(self._faults, sequence, 0), record=bool(record))
        what = describe_request(self.job.label, request)
        limit, by_deadline = limit_of(self.watchdog_seconds(world_size(world)), None if timeout is None else
                                      time.monotonic() + max(0.0, timeout), time.monotonic())
        started = time.perf_counter()
        future = self.cluster.client.submit(run_probe_task, self.job, request, fault_for(self._faults, sequence, 1),
                                            limit, by_deadline, pure=False, key=f"ddenv-probe-{uuid.uuid4().hex}")
        with self._lock:
            self._pending.add(future)
        try:
            done = self._result_of(future, what, limit, by_deadline)
        finally:
            with self._lock:
                self._pending.discard(future)
        return self._finish(done, what, limit, by_deadline, started, world_size(world))

    def _result_of(self, future: Any, what: str, limit: float | None, by_deadline: bool) -> TaskReply:
        """The task's `TaskReply`; the errors of the cluster (not of the probe) as `WorkerError`s."""
        from distributed import KilledWorker

        backstop = None if limit is None else limit + (DEADLINE_GRACE if by_deadline else
                                                       STARTUP_TIMEOUT + BACKSTOP_GRACE)
        try:
            done: TaskReply = future.result(timeout=backstop)
        except KilledWorker as error:
            self._stats.add("simulations")
            self._stats.add("crashes")
            self._stats.add("errors")
            raise WorkerError(f"probe of {what}: dask gave up after its workers died ({error})") from None
        except TimeoutError:
            future.cancel()
            if by_deadline:
                self._stats.add("cancelled")
                raise ProbeDeadline(f"probe of {what} was cancelled at the reduction's deadline") from None
            self._stats.add("timeouts")
            self._stats.add("errors")
            raise WorkerError(f"probe of {what}: the dask cluster did not answer within {backstop:g} s "
                              "(watchdog, probe process start and grace); the task was cancelled") from None
        except WorkerStartError as error:
            self._stats.add("errors")
            self._start_error = WorkerStartError(f"{self.job.label}: a dask worker could not start the test: {error}")
            raise self._start_error from None
        except WorkerError:
            self._stats.add("errors")
            raise
        except Exception as error:
            if self._closed or type(error).__name__ in ("CancelledError", "CommClosedError"):
                self._stats.add("errors")
                raise WorkerError(f"probe of {what} was lost by the dask cluster: {error!r}") from error
            raise
        return done

    def _finish(self, done: TaskReply, what: str, limit: float | None, by_deadline: bool, started: float,
                size: int = 0) -> Any:
        return finish(self._stats, done, what, limit, by_deadline, started, size)

    def close(self) -> None:
        self._closed = True
        with self._lock:
            pending, self._pending = list(self._pending), set()
        for future in pending:  # the threads waiting on them get CancelledError -> WorkerError at once
            with contextlib.suppress(Exception):
                future.cancel()
        if self._owns_cluster:
            self.cluster.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"DaskPool({self.job.label} on {self.cluster.address}{', closed' if self._closed else ''})"
