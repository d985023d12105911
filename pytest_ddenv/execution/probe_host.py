"""Probe processes hosted by a process of a distributed executor (a dask worker, a Ray actor): engine-neutral.

A host process keeps, per job, probe processes started the way `LocalPool` starts its workers (forkserver,
`worker_main`: the job's `serve` runs in the MAIN thread of its own process, over a pipe). `JobHost.run`
hands a probe to an idle probe process of its job (starting one on first use, so the test module is
imported once per probe process, not per probe), waits for the reply under the watchdog the pool sent,
kills a probe process that runs past it, and replaces one that dies (the probe is retried once, as on local
workers). It returns a `TaskReply` saying what happened; the pool turns it into the probe's result or
error. A host keeps the probe processes of its `JOBS_KEPT` most recently used jobs; they stop when it
stops (and are killed if it dies, on Linux).

Dask worker processes are daemonic by default (`distributed.worker.daemon`) and multiprocessing refuses to
start children from a daemonic process; that rule protects children from being orphaned when their parent is
terminated. Probe processes do not need it: they exit when the pipe to their host closes, and get SIGKILL
when it dies mid-probe (Linux: PR_SET_PDEATHSIG), so a daemonic host starts them all the same.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import sys
import threading
import time
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Any

from pytest_ddenv.execution.base import StatsBook
from pytest_ddenv.execution.errors import ProbeDeadline, WorkerError
from pytest_ddenv.execution.local import (
    STARTUP_TIMEOUT,
    WorkerDied,
    WorkerHung,
    WorkerProcess,
    default_context,
    forkserver_preload,
    shutdown_workers,
)
from pytest_ddenv.execution.request import Channel, FaultKind, Job, ProbeRequest, Reply

JOBS_KEPT = 4
"""Jobs a host process keeps probe processes for (least recently used first out)."""
CLOSE_GRACE = 1.0


@dataclass(frozen=True)
class TaskReply:
    """What a hosted probe returns: the probe process's `reply`, or `failure` ("hung": killed by the
    watchdog; "died": its probe process died on both tries) with `detail`; and what it cost: probe
    processes that died (`crashes`), probes re-run after a death (`retries`), probe processes started to
    replace dead or killed ones (`restarts`), tries started (`simulations`)."""

    reply: Reply | None
    failure: str | None = None
    detail: str = ""
    crashes: int = 0
    retries: int = 0
    restarts: int = 0
    simulations: int = 0
    host: str = ""
    """The host process and probe process that answered, e.g. 'dask worker node1 pid 812, probe process pid 840'."""


@dataclass(frozen=True)
class _OrphanSafeJob:
    """`job`, served by a probe process that gets SIGKILL when the process that started it dies (Linux),
    so that a probe hung at that moment does not outlive its host."""

    job: Job
    key: str = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "key", self.job.key)

    @property
    def label(self) -> str:
        return self.job.label

    def serve(self, channel: Channel) -> None:
        _die_with_parent()
        self.job.serve(channel)


def _die_with_parent() -> None:
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(Exception):  # best effort: no libc, no prctl
        import ctypes
        import signal

        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)


_daemon_lock = threading.Lock()


@contextlib.contextmanager
def _children_allowed() -> Iterator[None]:
    """Let this (possibly daemonic) host process start a child (see the module docstring)."""
    config: dict[str, Any] = getattr(multiprocessing.current_process(), "_config", {})
    with _daemon_lock:
        daemonic = bool(config.get("daemon"))
        if daemonic:
            config["daemon"] = False
        try:
            yield
        finally:
            if daemonic:
                config["daemon"] = True


_context_lock = threading.Lock()
_context: Any = None


def _probe_context() -> Any:
    """The start method of `LocalPool` (forkserver with its preloads, else spawn)."""
    global _context
    with _context_lock:
        if _context is None:
            method = default_context()
            _context = multiprocessing.get_context(method)
            if method == "forkserver":
                _context.set_forkserver_preload(forkserver_preload())
        return _context


class HostedJob:
    """The probe processes of one job on this host: one per probe running at once (a dask worker with
    several threads runs several), kept idle between probes. `host`: what the host is called in messages
    ('dask worker', 'ray actor')."""

    def __init__(self, job: Job, host: str) -> None:
        self.job = job
        self.host = host
        self._wrapped = _OrphanSafeJob(job)
        self._lock = threading.Lock()
        self._idle: list[WorkerProcess] = []
        self._live: set[WorkerProcess] = set()
        self._names = 0
        self.closed = False

    def _start(self) -> WorkerProcess:
        with self._lock:
            self._names += 1
            name = f"ddenv-probe-{self.job.key[:8]}-{self._names}"
        with _children_allowed():
            worker = WorkerProcess(_probe_context(), name, self._wrapped)
        with self._lock:
            self._live.add(worker)
        return worker

    def _acquire(self) -> tuple[WorkerProcess, bool]:
        """An idle probe process (True: it was started earlier), or a new one (False)."""
        with self._lock:
            while self._idle:
                worker = self._idle.pop()
                if worker.process.is_alive():
                    return worker, True
                self._live.discard(worker)
                worker.dispose()
        return self._start(), False

    def _forget(self, worker: WorkerProcess) -> None:
        with self._lock:
            self._live.discard(worker)
        worker.dispose()

    def _release(self, worker: WorkerProcess) -> None:
        with self._lock:
            if not self.closed:
                self._idle.append(worker)
                return
        self._forget(worker)

    def call(self, request: ProbeRequest, retry_fault: FaultKind | None, limit: float | None,
             by_deadline: bool) -> TaskReply:
        """Run `request` on a probe process; `limit`: seconds it may run (None: no limit), counted from now
        when `by_deadline` (the reduction's deadline includes starting the probe process), else from when
        the probe process is ready (the watchdog)."""
        begun = time.monotonic()
        worker, _ = self._acquire()
        counts = {"crashes": 0, "retries": 0, "restarts": 0, "simulations": 0}
        for try_index in (0, 1):
            attempt = request if try_index == 0 else replace(request, fault=retry_fault)
            try:
                if not worker.ready:
                    worker.await_ready(STARTUP_TIMEOUT)
                left = limit if limit is None or not by_deadline else max(0.0, limit - (time.monotonic() - begun))
                counts["simulations"] += 1
                reply = worker.call(attempt, left)
            except WorkerDied as died:
                self._forget(worker)
                counts["crashes"] += 1
                if try_index == 0 and not self.closed:
                    counts["retries"] += 1
                    counts["restarts"] += 1
                    worker = self._start()
                    continue
                return _task_reply(None, "died", died.how, _host(self.host), counts)
            except WorkerHung:
                self._forget(worker)
                return _task_reply(None, "hung", f"{worker} was killed", _host(self.host, worker), counts)
            except BaseException:  # could not start the job, or interrupted: the process's state is unknown
                self._forget(worker)
                raise
            self._release(worker)
            return _task_reply(reply, None, "", _host(self.host, worker), counts)
        raise AssertionError("unreachable")  # pragma: no cover

    def close(self, grace: float = CLOSE_GRACE) -> None:
        with self._lock:
            self.closed = True
            self._idle.clear()
        shutdown_workers(self._live, grace)


def _task_reply(reply: Reply | None, failure: str | None, detail: str, host: str, counts: dict[str, int]) -> TaskReply:
    return TaskReply(reply, failure, detail, crashes=counts["crashes"], retries=counts["retries"],
                     restarts=counts["restarts"], simulations=counts["simulations"], host=host)


def _host(host: str, worker: WorkerProcess | None = None) -> str:
    import os
    import socket

    here = f"{host} {socket.gethostname()} pid {os.getpid()}"
    return here if worker is None else f"{here}, probe process pid {worker.process.pid}"


class JobHost:
    """The hosted jobs of one host process, the `JOBS_KEPT` most recently used (a dask worker has one for
    the process; a Ray actor has its own)."""

    def __init__(self, host: str) -> None:
        self.host = host
        self.jobs: OrderedDict[str, HostedJob] = OrderedDict()
        self._lock = threading.Lock()

    def run(self, job: Job, request: ProbeRequest, retry_fault: FaultKind | None, limit: float | None,
            by_deadline: bool) -> TaskReply:
        """The probe on a probe process of `job` (see `HostedJob.call`). Raises `WorkerStartError` when the
        job cannot start here."""
        evicted: list[HostedJob] = []
        with self._lock:
            hosted = self.jobs.get(job.key)
            if hosted is None:
                hosted = self.jobs[job.key] = HostedJob(job, self.host)
                while len(self.jobs) > JOBS_KEPT:
                    evicted.append(self.jobs.popitem(last=False)[1])
            self.jobs.move_to_end(job.key)
        for old in evicted:  # in the background: a probe does not wait for another job's processes
            threading.Thread(target=old.close, name="ddenv-evict", daemon=True).start()
        return hosted.call(request, retry_fault, limit, by_deadline)

    def close(self) -> None:
        """Stop every probe process of this host."""
        with self._lock:
            hosted = list(self.jobs.values())
            self.jobs.clear()
        for job in hosted:
            job.close()


def worker_versions() -> dict[str, str]:
    """Runs on each host at connection time: what the pool checks for bit-identical runs."""
    from importlib.metadata import version

    from pytest_ddenv.world.limits import ENGINE_PACKAGES, engine_version

    return {"pytest-ddenv": version("pytest-ddenv"), **{engine: engine_version(engine) for engine in ENGINE_PACKAGES},
            "numpy": version("numpy")}


def finish(stats: StatsBook, done: TaskReply, what: str, limit: float | None, by_deadline: bool,
           started: float, size: int = 0) -> Any:
    """Where pytest runs: the probe's value from `done` (its error raised), counted in `stats`; a probe process
    killed by the watchdog (`WorkerError`) or at the deadline (`ProbeDeadline`), or that died twice
    (`WorkerError`). `started`: `time.perf_counter()` when the probe was sent; `size`: its world's
    `world_size` (for the watchdog)."""
    for name in ("simulations", "crashes", "retries", "restarts"):
        if getattr(done, name):
            stats.add(name, getattr(done, name))
    if done.failure == "hung":
        if by_deadline:
            stats.add("cancelled")
            raise ProbeDeadline(f"probe of {what} was stopped at the reduction's deadline; its probe process "
                                f"({done.host}) was killed")
        stats.add("timeouts")
        stats.add("errors")
        raise WorkerError(f"probe of {what} ran past the {limit:g} s watchdog; its probe process "
                          f"({done.host}) was killed")
    if done.failure is not None or done.reply is None:
        stats.add("errors")
        raise WorkerError(f"probe of {what} failed twice: its probe process died each time on {done.host} "
                          f"(last: {done.detail})")
    reply = done.reply
    stats.completed(time.perf_counter() - started - reply.seconds, reply.seconds, reply.cpu_seconds, size)
    if reply.error is not None:
        raise reply.error
    return reply.value


def version_problem(host: str, remote: dict[str, str]) -> str | None:
    """What differs between `remote` (a host's `worker_versions`) and this process's, as a sentence, or None."""
    mine = worker_versions()
    different = {k: v for k, v in remote.items() if mine.get(k) != v}
    if not different:
        return None
    shown = ", ".join(f"{k} {v} (here {mine.get(k)})" for k, v in sorted(different.items()))
    return f"{host} has {shown}; runs are bit-identical only with the same versions"


__all__ = ["JOBS_KEPT", "HostedJob", "JobHost", "TaskReply", "finish", "version_problem", "worker_versions"]
