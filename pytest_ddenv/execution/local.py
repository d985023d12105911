"""`LocalPool`: persistent local worker processes, each serving one `Job` (the user's test, imported once).

Thread-safe and blocking: each calling thread takes an idle worker, sends it one probe and waits for the
reply, the worker's death, or the watchdog. A worker that dies mid-probe is replaced and the probe retried
once on the fresh worker; a second death, a watchdog kill, or closing the pool raise `WorkerError`. A worker
that cannot start its job (the test does not import there) raises `WorkerStartError`, and so does every
later call. With ``in_process=handler`` probes run in the calling process instead (no worker process, no
fault isolation), one at a time; there the watchdog interrupts the probe with `ProbeTimeout` (`stuck.py`), and a
probe that defeats it sends the later probes to a worker process. The processes a probe starts end with it
(`children.py`): with its worker, or, in-process, when it returns.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import os
import queue
import signal
import sys
import threading
import time
import weakref
from collections.abc import Iterator, Sequence
from dataclasses import replace
from multiprocessing.connection import Connection, wait
from typing import TYPE_CHECKING, Any, Self

from pytest_ddenv.execution.base import (
    DEFAULT,
    DEFAULT_WATCHDOG_FACTOR,
    DEFAULT_WATCHDOG_FLOOR,
    PoolStats,
    StatsBook,
    check_watchdog,
    limit_of,
    run_cap_of,
    world_size,
)
from pytest_ddenv.execution.children import descendants, end_processes, processes_ended
from pytest_ddenv.execution.errors import (
    PoolConfigError,
    ProbeDeadline,
    WorkerError,
    WorkerStartError,
)
from pytest_ddenv.execution.request import (
    Fault,
    Handler,
    Job,
    ProbeRequest,
    Reply,
    answer,
    describe_request,
    fault_for,
    parse_faults,
)
from pytest_ddenv.execution.stuck import ProbeTimeout, ProbeWatchdog, Warn
from pytest_ddenv.execution.worker import worker_main
from pytest_ddenv.validation import expected, is_integer

if TYPE_CHECKING:
    from pytest_ddenv.world.model import World

STARTUP_TIMEOUT = 120.0
"""Seconds a new worker may take to start its job (import pybullet, the test module and what it imports)."""
CLOSE_GRACE = 1.0
"""Seconds `close()` lets workers exit on their own before terminating them."""
_PRELOAD = ["pytest_ddenv.execution.worker", "pytest_ddenv.sim", "pytest", "matplotlib.pyplot",
            "matplotlib.backends.backend_agg"]
"""matplotlib for the background media process (media/writer.py `BackgroundMedia`) of each reduction, which
draws its pictures first: 0.25 CPU-s once in the forkserver instead of in every one of them."""


def forkserver_preload() -> list[str]:
    """Modules the forkserver imports once, so that every worker forked from it starts with them: the
    simulation, pytest and the installed pytest plugins (a worker's pytest session loads them all; some,
    like hypothesis's, take a second to import), matplotlib's pyplot (`_PRELOAD`). Import errors are ignored
    by multiprocessing."""
    from importlib.metadata import entry_points

    plugins = sorted({entry.module for entry in entry_points(group="pytest11")})
    return [*_PRELOAD, *plugins]


def probe_context() -> Any:
    """The multiprocessing context the workers start from (forkserver with their preloads, else spawn), for
    other processes that should start as they do (the helper that renders an animation)."""
    method = default_context()
    context = multiprocessing.get_context(method)
    if method == "forkserver":
        context.set_forkserver_preload(forkserver_preload())
    return context


def cpu_count() -> int:
    """Cores this process may use (affinity-aware)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def resolve_workers(workers: int | str) -> int:
    """`workers` as a positive count: an int >= 1, a digit string, or 'auto' (one per core)."""
    if workers == "auto":
        return cpu_count()
    if isinstance(workers, str) and workers.strip().isdigit():
        workers = int(workers)
    if not is_integer(workers) or workers < 1:
        raise PoolConfigError(expected("an integer >= 1 or 'auto'", workers, "workers"))
    return workers


def default_context() -> str:
    return "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"


_main_lock = threading.Lock()


@contextlib.contextmanager
def main_module_hidden() -> Iterator[None]:
    """Start a worker without it re-importing the parent's __main__ (workers never need it): user scripts
    without an ``if __name__ == "__main__"`` guard would otherwise run again in every worker."""
    with _main_lock:
        main = sys.modules.get("__main__")
        if main is None:
            yield
            return
        saved: dict[str, Any] = {k: main.__dict__[k] for k in ("__file__", "__spec__") if k in main.__dict__}
        main.__dict__.pop("__file__", None)
        main.__dict__["__spec__"] = None
        try:
            yield
        finally:
            main.__dict__.pop("__spec__", None)
            main.__dict__.update(saved)


class WorkerDied(Exception):
    """A worker process died during a probe (`how`: its exit, for the message)."""

    def __init__(self, how: str) -> None:
        super().__init__(how)
        self.how = how


class WorkerHung(Exception):
    """A worker process ran past the watchdog during a probe (it is killed)."""


def _to_stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


class WorkerProcess:
    """One worker process and the parent's end of its pipe."""

    def __init__(self, context: Any, name: str, job: Job) -> None:
        parent, child = context.Pipe(duplex=True)
        self.process: Any = context.Process(target=worker_main, args=(child, job), name=name, daemon=True)
        with main_module_hidden():
            self.process.start()
        child.close()
        self.conn: Connection = parent
        self.name = name
        self.ready = False
        self.send_lock = threading.Lock()

    def __repr__(self) -> str:
        return f"worker {self.name} (pid {self.process.pid})"

    def exit_description(self) -> str:
        self.process.join(timeout=1.0)
        code = self.process.exitcode
        if code is None:
            return f"{self} stopped answering"
        if code < 0:
            try:
                return f"{self} was killed by {signal.Signals(-code).name}"
            except ValueError:  # pragma: no cover
                return f"{self} was killed by signal {-code}"
        return f"{self} exited with status {code}"

    def await_ready(self, timeout: float) -> None:
        status = self._wait(timeout)
        if status == "timeout":
            raise WorkerDied(f"{self} did not start within {timeout:g} s")
        try:
            message = self.conn.recv()
        except (EOFError, OSError):
            raise WorkerDied(f"{self.exit_description()} while starting") from None
        if message[0] == "failed":
            raise WorkerStartError(str(message[1]))
        self.ready = True

    def call(self, request: ProbeRequest, watchdog: float | None) -> Reply:
        try:
            with self.send_lock:
                self.conn.send(request)
        except (BrokenPipeError, OSError):
            raise WorkerDied(self.exit_description()) from None
        status = self._wait(watchdog)
        if status == "timeout":
            raise WorkerHung()
        try:
            reply = self.conn.recv()
        except (EOFError, OSError):
            raise WorkerDied(self.exit_description()) from None
        assert isinstance(reply, Reply)
        return reply

    def _wait(self, timeout: float | None) -> str:
        ready = wait([self.conn, self.process.sentinel], timeout)
        if self.conn in ready:
            return "reply"
        return "died" if ready else "timeout"

    def ask_to_stop(self) -> None:
        try:
            with self.send_lock:
                self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass

    def dispose(self, grace: float = 0.0) -> None:
        """Make sure the process is gone and reaped: wait `grace`, then terminate, then kill; and the processes
        its probes started with it (a worker ending on its own ends them itself)."""
        process = self.process
        if grace > 0:
            process.join(grace)
        started = descendants(process.pid) if process.is_alive() and process.pid is not None else []
        if process.is_alive():
            process.terminate()
            process.join(1.0)
        if process.is_alive():
            process.kill()
            process.join(5.0)
        end_processes(started)
        try:
            self.conn.close()
        except OSError:  # closed already: close() and a waiting thread may both dispose of a dead worker
            pass


def shutdown_workers(live: set[WorkerProcess], grace: float) -> None:
    """Ask every worker of `live` to stop, then kill those still running after `grace` seconds."""
    workers = list(live)
    for worker in workers:
        worker.ask_to_stop()
    deadline = time.monotonic() + grace
    for worker in workers:
        worker.dispose(max(0.0, deadline - time.monotonic()))
        live.discard(worker)


class LocalPool:
    """A pool of persistent local workers serving `job` (see the module docstring).

    `workers`: count or 'auto' (one per core). `in_process`: a handler `handler(world, attempt)` that runs
    probes in this process instead of worker processes (then `workers` must be 1). `watchdog`: wall-clock
    seconds a probe may take before its worker is killed (in-process: interrupted, see the module
    docstring), 'auto' (max(`watchdog_floor`, `watchdog_factor` x the longest of the original run, see
    `expect`, and the slowest probe so far)) or None (never); by default $DDENV_PROBE_TIMEOUT, else 'auto'.
    A hung probe is a `WorkerError`: an ERROR outcome, never a verdict. `context`: multiprocessing start method
    ('forkserver' where available, else 'spawn'; 'fork' is refused: pybullet and fork do not mix).
    `fault_injection`: test-only faults (see `Fault`); default from $DDENV_FAULT_INJECTION.
    """

    def __init__(
        self,
        job: Job,
        workers: int | str = "auto",
        *,
        in_process: Handler | None = None,
        watchdog: float | str | None = DEFAULT,
        watchdog_floor: float = DEFAULT_WATCHDOG_FLOOR,
        watchdog_factor: float = DEFAULT_WATCHDOG_FACTOR,
        context: str | None = None,
        fault_injection: str | Sequence[Fault] | None = None,
        startup_timeout: float = STARTUP_TIMEOUT,
        warn: Warn | None = None,
    ) -> None:
        if not isinstance(job, Job):
            raise PoolConfigError(f"a pool needs a Job (key, label, serve), got {type(job).__name__}")
        self.job = job
        self._size = resolve_workers(workers)
        self._watchdog = check_watchdog(watchdog)
        self._floor = float(watchdog_floor)
        self._factor = float(watchdog_factor)
        self._startup_timeout = float(startup_timeout)
        self._faults = parse_faults(fault_injection)
        self._handler = in_process
        self._stats = StatsBook(self._size)
        self._sequence = itertools.count(1)
        self._sequence_lock = threading.Lock()
        self._closed = False
        self._start_error: WorkerStartError | None = None
        self._idle: queue.Queue[WorkerProcess | None] = queue.Queue()
        self._live: set[WorkerProcess] = set()
        self._names = itertools.count(1)
        self._local_lock = threading.Lock()
        self._warn: Warn = warn or _to_stderr
        self.notes: list[str] = []
        """What the report should say about how this pool ran the probes (a probe moved to a worker process)."""
        self._method = context or default_context()
        if self._method == "fork":
            raise PoolConfigError("the 'fork' start method is not supported (pybullet is not fork-safe); "
                                  "use 'forkserver' or 'spawn'")
        if self._method not in multiprocessing.get_all_start_methods():
            raise PoolConfigError(f"unknown multiprocessing start method {self._method!r}; valid: "
                                  f"{', '.join(multiprocessing.get_all_start_methods())}")
        self._context: Any = None
        if in_process is not None:
            if self._size != 1:
                raise PoolConfigError(f"an in-process pool has exactly 1 worker, got workers={workers!r}")
            unsafe = sorted({f.kind for f in self._faults} - {"error", "hang"})
            if unsafe:
                raise PoolConfigError(f"fault(s) {', '.join(unsafe)} would take down the calling process; "
                                      "use worker processes to inject them")
        else:
            self._context = self._new_context()
            for _ in range(self._size):
                self._idle.put(self._start_worker(count=False))
        self._finalizer = weakref.finalize(self, shutdown_workers, self._live, 0.0)

    def _new_context(self) -> Any:
        context = multiprocessing.get_context(self._method)
        if self._method == "forkserver":
            context.set_forkserver_preload(forkserver_preload())
        return context

    # -- public API ----------------------------------------------------------------------------------
    @property
    def size(self) -> int:
        return self._size

    @property
    def in_process(self) -> bool:
        return self._handler is not None

    @property
    def stats(self) -> PoolStats:
        return self._stats.snapshot()

    @property
    def pids(self) -> list[int]:
        """Process ids of the live workers (empty in-process)."""
        return sorted(w.process.pid for w in list(self._live) if w.process.pid is not None)

    def watchdog_seconds(self, size: int = 0) -> float | None:
        """The watchdog the next probe, of a world of `size` (`world_size`; 0: unknown), gets (None: none); see
        `automatic_watchdog` for 'auto'."""
        if self._watchdog == "auto":
            return self._stats.watchdog(self._floor, self._factor, size, run_cap_of(self.job))
        return self._watchdog  # type: ignore[return-value]

    def expect(self, seconds: float, size: int = 0) -> None:
        """The original run of the test, a world of `size` (`world_size`; 0: unknown), took `seconds` (wall):
        the automatic watchdog is at least `watchdog_factor` times that."""
        self._stats.expect(seconds, size)

    def call(self, world: World, attempt: int, *, timeout: float | None = None, record: bool = False) -> Any:
        """Run the job's test on `world` as re-run `attempt` on a worker; return the handler's value.

        Raises what the handler raised (re-raised here), `WorkerStartError` when the workers cannot start
        the job, `ProbeDeadline` when the probe ran past `timeout` seconds (the caller's deadline: the worker
        is killed), or `WorkerError` when the pool could not complete the probe (worker died twice,
        watchdog, pool closed).
        """
        if self._closed:
            raise WorkerError("the worker pool is closed")
        if self._start_error is not None:
            raise self._start_error
        with self._sequence_lock:
            sequence = next(self._sequence)
        request = ProbeRequest(world, int(attempt), record=bool(record))
        deadline = None if timeout is None else time.monotonic() + max(0.0, float(timeout))
        if self._handler is not None:
            return self._call_here(replace(request, fault=fault_for(self._faults, sequence, 0)), deadline)
        return self._call_on_worker(request, sequence, deadline)  # (an in-process pool's too, once moved)

    def close(self, grace: float = CLOSE_GRACE) -> None:
        """Stop every worker (let them exit for `grace` seconds, then terminate/kill) and reap them."""
        self._closed = True
        shutdown_workers(self._live, grace)
        self._finalizer.detach()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        mode = "in-process" if self.in_process else f"{self._size} workers"
        return f"LocalPool({self.job.label}, {mode}{', closed' if self._closed else ''})"

    # -- in-process ----------------------------------------------------------------------------------
    def _call_here(self, request: ProbeRequest, deadline: float | None) -> Any:
        assert self._handler is not None
        what = describe_request(self.job.label, request)
        with self._local_lock:
            size = world_size(request.world)
            limit, by_deadline = limit_of(self.watchdog_seconds(size), deadline, time.monotonic())
            self._stats.add("simulations")
            started = time.perf_counter()
            watchdog = ProbeWatchdog(limit, what, self._warn)
            stopped = False
            try:
                with processes_ended(exclude=self.pids), watchdog:
                    reply = answer(request, self._handler)
            except ProbeTimeout:
                stopped = True
            over = stopped or watchdog.ran_past_limit()
            if watchdog.defeat is not None or (over and not stopped):
                self._move_to_workers(what, limit if over else None, watchdog.defeat or "it did not stop when "
                                      "interrupted")
            if over:
                self._stats.add("cancelled" if by_deadline else "timeouts")
                if by_deadline:
                    raise ProbeDeadline(f"probe of {what} was stopped at the reduction's deadline") from None
                self._stats.add("errors")
                how = "it was interrupted" if watchdog.defeat is None and stopped else (
                    f"it did not stop when interrupted ({watchdog.defeat or 'it went on'}) and "
                    + ("was stopped by harder interrupts" if stopped else "its result is not used"))
                raise WorkerError(f"probe of {what} ran past the {limit:g} s watchdog in this process; {how}") \
                    from None
        return self._finish(reply, started, size)

    def _move_to_workers(self, what: str, limit: float | None, why: str) -> None:
        """A probe defeated the in-process watchdog (past its `limit`, or None: it finished in time but
        replaced the SIGALRM handler): the later probes run in a worker process (where a hung probe's worker
        is killed); the report says so."""
        if self._handler is None:
            return
        self._handler = None
        self._context = self._new_context()
        self._idle.put(None)
        how = (f"{why}, which defeats the watchdog of probes in this process" if limit is None
               else f"ran in this process past its {limit:g} s watchdog and {why}")
        self.notes.append(f"the probe of {what} {how}; the later probes ran in a worker process, where a probe "
                          "that hangs has its worker killed")

    # -- worker processes ----------------------------------------------------------------------------
    def _call_on_worker(self, request: ProbeRequest, sequence: int, deadline: float | None) -> Any:
        what = describe_request(self.job.label, request)
        size = world_size(request.world)
        worker = self._acquire()
        for try_index in (0, 1):
            attempt = replace(request, fault=fault_for(self._faults, sequence, try_index))
            try:
                if not worker.ready:
                    worker.await_ready(self._startup_timeout)
                watchdog, by_deadline = limit_of(self.watchdog_seconds(size), deadline, time.monotonic())
                self._stats.add("simulations")
                started = time.perf_counter()
                reply = worker.call(attempt, watchdog)
            except WorkerStartError as error:
                self._forget(worker)
                self._stats.add("errors")
                self._start_error = WorkerStartError(
                    f"{self.job.label}: a probe worker could not start the test: {error}"
                )
                raise self._start_error from None
            except WorkerDied as died:
                retry = try_index == 0 and not self._closed
                self._forget(worker, free_slot=not retry)
                self._raise_if_closed(what)
                self._stats.add("crashes")
                if retry:
                    self._stats.add("retries")
                    worker = self._start_worker()
                    continue
                self._stats.add("errors")
                raise WorkerError(f"probe of {what} failed twice: its worker died each time "
                                  f"(last: {died.how})") from None
            except WorkerHung:
                self._forget(worker)
                self._raise_if_closed(what)
                if by_deadline:
                    self._stats.add("cancelled")
                    raise ProbeDeadline(f"probe of {what} was stopped at the reduction's deadline; its worker was "
                                        "killed") from None
                self._stats.add("timeouts")
                self._stats.add("errors")
                raise WorkerError(f"probe of {what} ran past the {watchdog:g} s watchdog; "
                                  "its worker was killed") from None
            except BaseException:  # interrupted mid-call: the worker's state is unknown
                self._forget(worker)
                self._stats.add("errors")
                raise
            self._release(worker)
            return self._finish(reply, started, size)
        raise AssertionError("unreachable")  # pragma: no cover

    def _finish(self, reply: Reply, started: float, size: int) -> Any:
        self._stats.completed(time.perf_counter() - started - reply.seconds, reply.seconds, reply.cpu_seconds,
                              size)
        if reply.error is not None:
            raise reply.error
        return reply.value

    def _raise_if_closed(self, what: str) -> None:
        if self._closed:
            self._stats.add("errors")
            raise WorkerError(f"the worker pool was closed while running the probe of {what}")

    def _start_worker(self, *, count: bool = True) -> WorkerProcess:
        assert self._context is not None
        worker = WorkerProcess(self._context, f"ddenv-probe-{next(self._names)}", self.job)
        self._live.add(worker)
        if count:
            self._stats.add("restarts")
        if self._closed:  # close() raced with us: do not leave it behind
            self._forget(worker, free_slot=False)
            raise WorkerError("the worker pool is closed")
        return worker

    def _forget(self, worker: WorkerProcess, *, free_slot: bool = True) -> None:
        """Kill (if needed) and reap a worker whose state is unknown or dead. With `free_slot`, its slot goes
        back to the idle queue empty (a new worker starts when someone needs it)."""
        self._live.discard(worker)
        worker.dispose()
        if free_slot and not self._closed:
            self._idle.put(None)

    def _acquire(self) -> WorkerProcess:
        while True:
            if self._closed:
                raise WorkerError("the worker pool is closed")
            if self._start_error is not None:
                raise self._start_error
            try:
                item = self._idle.get(timeout=0.2)
            except queue.Empty:
                continue
            if item is None:
                return self._start_worker()
            if item.process.is_alive():
                return item
            self._live.discard(item)  # died while idle
            item.dispose()
            self._stats.add("crashes")
            return self._start_worker()

    def _release(self, worker: WorkerProcess) -> None:
        if self._closed:
            return
        self._idle.put(worker)
