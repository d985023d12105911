"""Probes on a Ray cluster (optional extra `ray`): `RayCluster` is the connection (a session shares one),
`RayPool` runs the probes of one `Job` on it with the `Pool` API.

The cluster holds one actor (`ray_host.ProbeSlot`, 1 CPU) per probe that can run at once; a probe takes an
idle actor, which runs it on a probe process of its own (`probe_host.py`: the test in the main thread of
that process, started on the first probe of the job and kept; the watchdog kills a probe process past it;
one that dies is replaced and its probe retried once). An actor that dies or stops answering is killed
and replaced; the probe it ran is a `WorkerError`. ``"ray"`` starts a local head node for the session
(`ray_head.py`: its own ports, temporary folder and token, no dashboard, ended with the session);
``ray://host:port`` connects to a running cluster through the Ray client. The actors belong to the
session's connection: Ray ends them when it closes or the session dies. Ray's connection is one per
process (`ray.init`), so a session that already has one (its tests use Ray) cannot use the ray executor.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import sys
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any, Self

from pytest_ddenv.execution.base import (
    DEFAULT,
    DEFAULT_WATCHDOG_FACTOR,
    DEFAULT_WATCHDOG_FLOOR,
    ClusterPoolBase,
    limit_of,
    world_size,
)
from pytest_ddenv.execution.errors import PoolConfigError, ProbeDeadline, WorkerError, WorkerStartError
from pytest_ddenv.execution.local import STARTUP_TIMEOUT
from pytest_ddenv.execution.probe_host import TaskReply, finish, version_problem
from pytest_ddenv.execution.request import Fault, Job, ProbeRequest, describe_request, fault_for, parse_faults
from pytest_ddenv.world.model import World

ADDRESS_SCHEME = "ray://"
DEADLINE_GRACE = 2.0
"""Seconds past a probe's deadline the pool waits for the actor to report that it stopped the probe, before
it kills the actor."""
BACKSTOP_GRACE = 30.0
"""Seconds past its watchdog (and the time a probe process may take to start) the pool waits for an actor
that does not answer before it kills and replaces it."""
POLL = 0.25
"""Seconds between two looks at a probe's result (a closed pool is noticed within this)."""
CLIENT_TRIES = 3
SERVER_FAILED = "Initialization failure from server"
"""What the Ray client says when the cluster's client server could not start the session's server."""

__all__ = ["RayCluster", "RayPool"]


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise PoolConfigError("the ray executor needs ray: pip install 'pytest-ddenv[ray]'") from None
    return ray


class RayCluster:
    """A connection to a Ray cluster and its probe actors, one per CPU: a local head node of `n_workers` CPUs
    started for this session (`address` None or "ray"), or a running cluster at ray://host:port (`n_workers`
    of its CPUs, or all that are free at connection time). Checks that every actor has the same pytest-ddenv,
    pybullet, mujoco and numpy."""

    def __init__(self, address: str | None = None, *, n_workers: int | None = None,
                 check_versions: bool = True) -> None:
        from pytest_ddenv.execution.local import cpu_count, resolve_workers
        from pytest_ddenv.execution.ray_head import LocalHead

        ray = _import_ray()
        local = address in (None, "ray")
        if not local and not (isinstance(address, str) and address.startswith(ADDRESS_SCHEME)):
            raise PoolConfigError(f"ray executor address must be 'ray' (a local cluster) or a Ray client address "
                                  f"like ray://host:10001, got {address!r}")
        if ray.is_initialized():
            raise PoolConfigError("the ray executor needs this process's Ray connection, and it is already open "
                                  "(ray.init was called): use --ddenv-executor local or dask here")
        self.closed = False
        self._head: Any = None
        self._actors: list[Any] = []
        self._idle: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._environ: dict[str, str | None] = {}
        count = cpu_count() if n_workers is None else resolve_workers(n_workers)
        if local:
            self._head = LocalHead(count)
            self._environ = {name: os.environ.get(name) for name in self._head.environ}
            os.environ.update(self._head.environ)
        self.address = "ray (local, " + self._head.address + ")" if local else str(address)
        _read_auth_settings()
        try:
            _connect(ray, self._head.address if local else str(address))
        except Exception as error:
            self._close_head()
            raise PoolConfigError(f"cannot connect to the Ray cluster at {self.address}: {error}") from error
        try:
            if not local:
                free = int(ray.available_resources().get("CPU", 0))
                count = free if n_workers is None else count
                if count < 1 or count > free:
                    raise PoolConfigError(f"the Ray cluster at {self.address} has {free} free CPUs: the ray executor "
                                          f"needs one per probe running at once ({max(1, count)} asked for)")
            self._slot = ray.remote(num_cpus=1, max_restarts=0, max_concurrency=1)(_slot_class())
            self._sys_path = tuple(sys.path) if local else ()
            for _ in range(count):
                self._add_actor()
            if check_versions:
                self._check_versions()
        except BaseException:
            self.close()
            raise

    @property
    def threads(self) -> int:
        """Probes the cluster can run at once."""
        return len(self._actors)

    def _add_actor(self) -> None:
        actor = self._slot.remote(self._sys_path)
        with self._lock:
            self._actors.append(actor)
        self._idle.put(actor)

    def _check_versions(self) -> None:
        ray = _import_ray()
        try:
            remote = ray.get([actor.versions.remote() for actor in self._actors], timeout=STARTUP_TIMEOUT)
        except ray.exceptions.GetTimeoutError:
            raise PoolConfigError(f"the {len(self._actors)} probe actors did not start on the Ray cluster at "
                                  f"{self.address} within {STARTUP_TIMEOUT:g} s") from None
        except Exception as error:  # typically ModuleNotFoundError in the actor
            raise PoolConfigError(
                f"the Ray workers at {self.address} cannot run pytest-ddenv ({type(error).__name__}: {error}); "
                "install the same pytest-ddenv, pybullet, mujoco and numpy on every node"
            ) from error
        for index, versions in enumerate(remote):
            problem = version_problem(f"ray actor {index}", versions)
            if problem is not None:
                raise PoolConfigError(problem)

    def acquire(self, stop: Callable[[], bool]) -> Any:
        """An idle actor, waiting for one; `WorkerError` when the cluster closes or `stop()` says so."""
        while True:
            if self.closed or stop():
                raise WorkerError("the ray pool is closed")
            try:
                return self._idle.get(timeout=POLL)
            except queue.Empty:
                continue

    def release(self, actor: Any) -> None:
        self._idle.put(actor)

    def replace(self, actor: Any) -> None:
        """Kill `actor` (it died, or does not answer; its probe processes die with it) and start another."""
        with self._lock:
            if actor in self._actors:
                self._actors.remove(actor)
        with contextlib.suppress(Exception):
            _import_ray().kill(actor, no_restart=True)
        if not self.closed:
            self._add_actor()

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        ray = _import_ray()
        with self._lock:
            actors, self._actors = list(self._actors), []
        with contextlib.suppress(Exception):  # best effort: let the actors stop their probe processes
            ray.get([actor.close.remote() for actor in actors], timeout=10)
        for actor in actors:
            with contextlib.suppress(Exception):
                ray.kill(actor, no_restart=True)
        with contextlib.suppress(Exception):
            ray.shutdown()
        self._close_head()

    def _close_head(self) -> None:
        if self._head is not None:
            self._head.close()
            self._head = None
        for name, value in self._environ.items():  # as it was before the head's token
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if self._environ:
            _read_auth_settings()
        self._environ = {}

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _connect(ray: Any, address: str) -> None:
    """`ray.init` to `address`; a Ray client connection is tried up to `CLIENT_TRIES` times when the server
    fails to start the session's end of it: the client server of a fresh head sometimes does on the first
    connections (Ray 2.60: "Starting Ray client server failed", a `ZombieProcess` in its proxier)."""
    for tries_left in reversed(range(CLIENT_TRIES)):
        try:
            ray.init(address=address, namespace=f"ddenv-{uuid.uuid4().hex[:8]}", logging_level=logging.ERROR,
                     log_to_driver=False)
            return
        except ConnectionError as error:
            if not tries_left or not address.startswith(ADDRESS_SCHEME) or SERVER_FAILED not in str(error):
                raise
            with contextlib.suppress(Exception):
                ray.shutdown()


def _read_auth_settings() -> None:
    """Make Ray read its token authentication settings ($RAY_AUTH_MODE, $RAY_AUTH_TOKEN) from the environment
    again, as its own `ray.init()` does when it turns them on: this process may have read them before they
    were set (at its first `import ray`)."""
    import importlib

    with contextlib.suppress(ImportError, AttributeError):  # a Ray without token authentication
        raylet = importlib.import_module("ray._raylet")
        raylet.Config.initialize("")
        raylet.AuthenticationTokenLoader.instance().reset_cache()


def _slot_class() -> type:
    from pytest_ddenv.execution.ray_host import ProbeSlot

    return ProbeSlot


class RayPool(ClusterPoolBase):
    """The probes of `job` on a `RayCluster` (the `Pool` API); `watchdog`, `fault_injection` and
    `owns_cluster` as for `DaskPool`. The watchdog runs in the actor (the time a probe waited for an idle
    actor and its probe process took to start is not counted). `close()` makes the threads waiting on
    probes return at once (`WorkerError`); the actors that ran them are replaced."""

    def __init__(
        self,
        job: Job,
        cluster: RayCluster,
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
        self.notes: list[str] = []
        """Nothing to say so far: a ray pool changes nothing on its own (`Pool.notes`)."""

    def call(self, world: World, attempt: int, *, timeout: float | None = None, record: bool = False) -> Any:
        """Like `LocalPool.call`, on the cluster."""
        if self._closed or self.cluster.closed:
            raise WorkerError("the ray pool is closed")
        if self._start_error is not None:
            raise self._start_error
        with self._lock:
            self._sequence += 1
            sequence = self._sequence
        request = ProbeRequest(world, int(attempt), fault_for(self._faults, sequence, 0), record=bool(record))
        what = describe_request(self.job.label, request)
        deadline = None if timeout is None else time.monotonic() + max(0.0, timeout)
        actor = self.cluster.acquire(lambda: self._closed)
        limit, by_deadline = limit_of(self.watchdog_seconds(world_size(world)), deadline, time.monotonic())
        started = time.perf_counter()
        reference = actor.probe.remote(self.job, request, fault_for(self._faults, sequence, 1), limit, by_deadline)
        done = self._result_of(reference, actor, what, limit, by_deadline)
        self.cluster.release(actor)
        return finish(self._stats, done, what, limit, by_deadline, started, world_size(world))

    def _result_of(self, reference: Any, actor: Any, what: str, limit: float | None, by_deadline: bool) -> TaskReply:
        """The actor's `TaskReply`; the errors of the cluster (not of the probe) as `WorkerError`s. The actor
        is replaced when it died or did not answer, released when it raised."""
        ray = _import_ray()
        backstop = None if limit is None else limit + (DEADLINE_GRACE if by_deadline else
                                                       STARTUP_TIMEOUT + BACKSTOP_GRACE)
        give_up = None if backstop is None else time.monotonic() + backstop
        try:
            while not ray.wait([reference], timeout=POLL if give_up is None else
                               max(0.0, min(POLL, give_up - time.monotonic())))[0]:
                if self._closed or self.cluster.closed:
                    raise _Abandoned(f"probe of {what}: the ray pool was closed while it ran", "closed")
                if give_up is not None and time.monotonic() >= give_up:
                    if by_deadline:
                        raise _Abandoned(f"probe of {what} was cancelled at the reduction's deadline", "deadline")
                    raise _Abandoned(f"probe of {what}: its ray actor did not answer within {backstop:g} s "
                                     "(watchdog, probe process start and grace); the actor was killed", "timeout")
            done: TaskReply = ray.get(reference)
        except _Abandoned as abandoned:
            self.cluster.replace(actor)
            self._stats.add("simulations")  # sent to an idle actor: it started
            if abandoned.kind == "deadline":
                self._stats.add("cancelled")
                raise ProbeDeadline(str(abandoned)) from None
            if abandoned.kind == "timeout":
                self._stats.add("timeouts")
            self._stats.add("errors")
            raise WorkerError(str(abandoned)) from None
        except ray.exceptions.RayActorError as error:
            self.cluster.replace(actor)
            for name in ("simulations", "crashes", "errors"):
                self._stats.add(name)
            raise WorkerError(f"probe of {what}: its ray actor died ({_first_line(error)})") from None
        except ray.exceptions.RayTaskError as error:
            self.cluster.release(actor)
            cause = getattr(error, "cause", None)
            self._stats.add("errors")
            if isinstance(cause, WorkerStartError):
                self._start_error = WorkerStartError(f"{self.job.label}: a ray actor could not start the test: "
                                                     f"{cause}")
                raise self._start_error from None
            if isinstance(cause, WorkerError):
                raise cause from None
            raise WorkerError(f"probe of {what} failed in its ray actor: {_first_line(error)}") from error
        except Exception as error:  # the connection to the cluster was lost, ...
            self.cluster.replace(actor)
            self._stats.add("errors")
            raise WorkerError(f"probe of {what} was lost by the ray cluster: {_first_line(error)}") from error
        return done

    def close(self) -> None:
        self._closed = True
        if self._owns_cluster:
            self.cluster.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RayPool({self.job.label} on {self.cluster.address}{', closed' if self._closed else ''})"


class _Abandoned(Exception):
    """A probe the pool stopped waiting for (its actor is replaced): the pool was `closed`, the caller's
    `deadline` passed, or the actor did not answer in time (`timeout`)."""

    def __init__(self, message: str, kind: str) -> None:
        super().__init__(message)
        self.kind = kind


def _first_line(error: BaseException) -> str:
    lines = [line for line in str(error).splitlines() if line.strip()]
    return f"{type(error).__name__}: {lines[0] if lines else ''}"
