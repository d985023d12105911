"""`DaskSimulationPool`: the same `simulate` API on a dask.distributed cluster (optional extra `dask`).

Every dask worker thread keeps one live `Simulator` (`simulate_task` below, imported by name on the
workers: pytest-ddenv must be installed there). ``address=None`` or ``"dask"`` starts a LocalCluster of
worker processes bound to 127.0.0.1; ``tcp://host:port`` (or ``tls://``) connects to a running scheduler.
Dask already reschedules the tasks of a worker that dies; after `distributed.scheduler.allowed-failures`
deaths it gives up (KilledWorker), which becomes `SimulationError`.
"""

from __future__ import annotations

import contextlib
import threading
import time
import uuid
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Self

from pytest_ddenv.execution.base import (
    DEFAULT_WATCHDOG_FACTOR,
    DEFAULT_WATCHDOG_FLOOR,
    PoolStats,
    StatsBook,
    check_preload,
    check_watchdog,
)
from pytest_ddenv.execution.errors import PoolConfigError, SimulationError
from pytest_ddenv.execution.request import (
    Fault,
    Reply,
    SimRequest,
    describe_request,
    execute,
    fault_for,
    parse_faults,
)

if TYPE_CHECKING:
    from pytest_ddenv.execution.request import PredicateLike
    from pytest_ddenv.sim import Run, RunSettings, Simulator
    from pytest_ddenv.world import World

ADDRESS_SCHEMES = ("tcp://", "tls://")
CONNECT_TIMEOUT = 30.0
_local = threading.local()


def simulate_task(request: SimRequest) -> Reply:
    """Runs on a dask worker: one Simulator per worker thread, created on first use, kept alive."""
    simulator: Simulator | None = getattr(_local, "simulator", None)
    if simulator is None or simulator.client < 0:
        from pytest_ddenv.sim import Simulator

        simulator = Simulator()
        _local.simulator = simulator
    return execute(simulator, request)


def worker_versions() -> dict[str, str]:
    """Runs on each dask worker at connection time: what the pool checks for bit-identical runs."""
    from importlib.metadata import version

    return {"pytest-ddenv": version("pytest-ddenv"), "pybullet": version("pybullet"), "numpy": version("numpy")}


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise PoolConfigError(
            "the dask executor needs dask.distributed: pip install 'pytest-ddenv[dask]' (or 'dask[distributed]')"
        ) from None
    return distributed


class DaskSimulationPool:
    """Simulations on a dask.distributed cluster (see the module docstring).

    `n_workers` sizes a local cluster (default: one per core). `watchdog` as for `SimulationPool`, except
    that dask cannot kill a running task: a simulation past the watchdog is cancelled and reported as
    `SimulationError`, its worker thread finishes it in the background (the simulated time limit bounds it).
    `fault_injection` supports only 'error' (a raising simulation) on dask. `preload`: modules every dask
    worker imports (now and when it restarts), e.g. the one registering a custom robot.
    """

    def __init__(
        self,
        address: str | None = None,
        *,
        n_workers: int | None = None,
        watchdog: float | str | None = "auto",
        watchdog_floor: float = DEFAULT_WATCHDOG_FLOOR,
        watchdog_factor: float = DEFAULT_WATCHDOG_FACTOR,
        fault_injection: str | Sequence[Fault] | None = None,
        connect_timeout: float = CONNECT_TIMEOUT,
        check_versions: bool = True,
        preload: Sequence[str] = (),
    ) -> None:
        from pytest_ddenv.execution.local import cpu_count, resolve_workers

        distributed = _import_distributed()
        self._watchdog = check_watchdog(watchdog)
        self._floor, self._factor = float(watchdog_floor), float(watchdog_factor)
        self._faults = parse_faults(fault_injection)
        unsupported = sorted({f.kind for f in self._faults} - {"error"})
        if unsupported:
            raise PoolConfigError(f"fault(s) {', '.join(unsupported)} cannot be injected on dask (only 'error')")
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
            self._client: Any = distributed.Client(self._cluster or address, timeout=connect_timeout,
                                                   set_as_default=False)
        except (OSError, TimeoutError) as error:
            self._close_cluster()
            raise PoolConfigError(f"cannot connect to the dask scheduler at {address}: {error}") from error
        try:
            if not local:
                self._client.wait_for_workers(1, timeout=connect_timeout)
            if check_versions:
                self._check_versions()
            modules = check_preload(preload)
            if modules:
                from pytest_ddenv.execution.dask_preload import PreloadModules

                self._client.register_plugin(PreloadModules(modules))
        except BaseException:
            self.close()
            raise
        self._size = max(1, int(sum(self._client.nthreads().values())))
        self._stats = StatsBook(self._size)
        self._sequence = 0
        self._lock = threading.Lock()
        self._closed = False

    # -- public API ----------------------------------------------------------------------------------
    @property
    def size(self) -> int:
        return self._size

    @property
    def stats(self) -> PoolStats:
        return self._stats.snapshot()

    @property
    def client(self) -> Any:
        return self._client

    def watchdog_seconds(self) -> float | None:
        if self._watchdog == "auto":
            return self._stats.watchdog(self._floor, self._factor)
        return self._watchdog  # type: ignore[return-value]

    def simulate(
        self,
        world: World,
        *,
        seed: int,
        predicates: Sequence[PredicateLike] = (),
        settings: RunSettings | None = None,
        timeout: float | None = None,
    ) -> Run:
        """Like `SimulationPool.simulate`, on the cluster."""
        from distributed import KilledWorker

        from pytest_ddenv.sim import RunSettings

        if self._closed:
            raise SimulationError("the dask simulation pool is closed")
        with self._lock:
            self._sequence += 1
            sequence = self._sequence
        request = SimRequest(world, seed, tuple(predicates), settings or RunSettings(), timeout,
                             fault_for(self._faults, sequence, 0))
        what = describe_request(request)
        watchdog = self.watchdog_seconds()
        started = time.perf_counter()
        future = self._client.submit(simulate_task, request, pure=False, key=f"ddenv-sim-{uuid.uuid4().hex}")
        try:
            reply: Reply = future.result(timeout=watchdog)
        except KilledWorker as error:
            self._stats.add("crashes")
            self._stats.add("errors")
            raise SimulationError(f"simulation of {what}: dask gave up after its workers died ({error})") from None
        except TimeoutError:
            future.cancel()
            self._stats.add("timeouts")
            self._stats.add("errors")
            raise SimulationError(f"simulation of {what} ran past the {watchdog:g} s watchdog on dask") from None
        except Exception as error:
            if self._closed or type(error).__name__ in ("CancelledError", "CommClosedError"):
                self._stats.add("errors")
                raise SimulationError(f"simulation of {what} was lost by the dask cluster: {error!r}") from error
            raise
        self._stats.completed(time.perf_counter() - started - reply.seconds, reply.seconds)
        if reply.error is not None:
            raise reply.error
        assert reply.run is not None
        return reply.run

    def close(self) -> None:
        self._closed = True
        client = getattr(self, "_client", None)
        if client is not None:
            with contextlib.suppress(Exception):  # best effort at shutdown
                client.close(timeout=10)
        self._close_cluster()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"DaskSimulationPool({self.address}{', closed' if self._closed else ''})"

    # -- helpers -------------------------------------------------------------------------------------
    def _close_cluster(self) -> None:
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close(timeout=10)
            self._cluster = None

    def _check_versions(self) -> None:
        try:
            remote: dict[str, dict[str, str]] = self._client.run(worker_versions)
        except Exception as error:  # typically ModuleNotFoundError on the worker
            raise PoolConfigError(
                f"the dask workers at {self.address} cannot run pytest-ddenv ({type(error).__name__}: {error}); "
                "install the same pytest-ddenv, pybullet and numpy on every worker"
            ) from error
        mine = worker_versions()
        for worker, versions in sorted(remote.items()):
            different = {k: v for k, v in versions.items() if mine.get(k) != v}
            if different:
                shown = ", ".join(f"{k} {v} (here {mine.get(k)})" for k, v in sorted(different.items()))
                raise PoolConfigError(
                    f"dask worker {worker} has {shown}; runs are bit-identical only with the same versions"
                )
