"""`make_pool`: the pool the command-line options ask for."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pytest_ddenv.execution.base import Pool
from pytest_ddenv.execution.dask_pool import DaskCluster, DaskPool
from pytest_ddenv.execution.errors import PoolConfigError
from pytest_ddenv.execution.local import LocalPool, cpu_count, default_context, probe_context, resolve_workers
from pytest_ddenv.execution.request import Handler, Job
from pytest_ddenv.validation import expected

if TYPE_CHECKING:
    from pytest_ddenv.execution.ray_pool import RayCluster


IDLE_SAMPLE_SECONDS = 0.1
"""How long `idle_cores` watches the machine's CPU time (/proc/stat) to see how much of it others use."""


def idle_cores(sample: float = IDLE_SAMPLE_SECONDS, ours: Sequence[int] = ()) -> int:
    """How many cores other processes leave idle now, at least 1 and at most the cores this process may use
    (`cpu_count`: its affinity): the idle share of the machine's CPU time over `sample` seconds (Linux's
    /proc/stat), else the cores minus the 1-minute load average (which lags by a minute). This process sleeps
    while it measures, so its own work is not counted, nor the work of the processes `ours` names (this
    session's background media, which end within seconds: they must not make a reduction run on one core)."""
    cores = cpu_count()
    try:
        idle = _idle_share(sample, ours) * (os.cpu_count() or 1)
    except (OSError, ValueError, IndexError):  # not Linux
        try:
            idle = cores - os.getloadavg()[0]
        except OSError:  # pragma: no cover - no load average either
            return cores
    return max(1, min(cores, round(idle)))


def _idle_share(sample: float, ours: Sequence[int] = ()) -> float:
    """The share of the machine's CPU time spent idle over `sample` seconds (/proc/stat's first line: user,
    nice, system, idle, iowait, irq, softirq, steal), the time the processes `ours` used counted as idle
    (/proc/PID/stat's utime and stime, in the same clock ticks; a process that ended counts as nothing)."""
    def times() -> list[int]:
        with open("/proc/stat", encoding="ascii") as stat:
            return [int(value) for value in stat.readline().split()[1:9]]

    before, mine = times(), _ticks(ours)
    time.sleep(sample)
    spent = [b - a for a, b in zip(before, times(), strict=True)]
    total = sum(spent)
    used_by_ours = sum(max(0, after - ticks) for ticks, after in zip(mine, _ticks(ours), strict=True))
    return 1.0 if total <= 0 else min(total, spent[3] + spent[4] + used_by_ours) / total


def _ticks(pids: Sequence[int]) -> list[int]:
    """The user + system clock ticks of each process (0: it is gone)."""
    ticks = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()  # after the command's name, which may hold spaces
            ticks.append(int(fields[11]) + int(fields[12]))  # utime, stime: fields 14 and 15 of proc(5)
        except (OSError, ValueError, IndexError):
            ticks.append(0)
    return ticks


def default_workers(workers: int | str) -> int:
    """The worker count of `workers` ('auto': `idle_cores()`, the cores other processes leave idle; a number
    stays as given)."""
    return idle_cores() if workers == "auto" else resolve_workers(workers)


def start_forkserver() -> None:
    """Start the forkserver the local workers are forked from (`probe_context`: it imports the simulation,
    pytest and its plugins once, in its own process), if it is not running: a caller that knows it will soon
    start workers calls this first, and they start from a warm server. Returns at once (the imports happen
    in the server); nothing where the workers are spawned."""
    if default_context() == "forkserver":
        import multiprocessing.forkserver

        probe_context()  # sets the server's preloads
        multiprocessing.forkserver.ensure_running()


def executor_problem(executor: str) -> str | None:
    """Why `executor` is not 'local', 'dask', a dask scheduler address tcp://HOST:PORT (tls://...), 'ray' or a
    Ray client address ray://HOST:PORT, or None. Only the form is checked: whether the scheduler answers is
    known when a reduction connects to it."""
    from urllib.parse import urlsplit

    if executor in ("local", "dask", "ray"):
        return None
    forms = ("'local', 'dask' or a dask scheduler address tcp://HOST:PORT (or tls://HOST:PORT), "
             "or 'ray' or a Ray client address ray://HOST:PORT")
    try:
        parts = urlsplit(executor)
        port = parts.port
    except ValueError:  # a port that is not a number from 0 to 65535
        return expected(forms, executor)
    if parts.scheme not in ("tcp", "tls", "ray") or not parts.hostname or not port or parts.path not in ("", "/") or (
            parts.query or parts.fragment or parts.username):
        return expected(forms, executor)
    return None


def check_executor(executor: str | None) -> str | None:
    """None for local worker processes, else "dask", "ray" or a cluster's address (PoolConfigError if invalid)."""
    if executor in (None, "", "local"):
        return None
    problem = executor_problem(executor) if isinstance(executor, str) else expected("a string", executor)
    if problem is not None:
        raise PoolConfigError(f"executor: {problem}")
    return executor


def is_ray(executor: str) -> bool:
    """`executor` (checked) names a Ray cluster: 'ray' or ray://HOST:PORT."""
    return executor == "ray" or executor.startswith("ray://")


def make_cluster(executor: str, workers: int | str = "auto") -> DaskCluster | RayCluster:
    """The connection to the distributed executor `executor` names ("dask" or "ray": a local cluster of
    `workers` processes; a dask scheduler's or Ray cluster's address), which a session opens on its first
    failure and keeps for every reduction (`make_pool(..., cluster=)`); the caller closes it (`close()`)."""
    kind = check_executor(executor)
    if kind is None:
        raise PoolConfigError("executor: local worker processes need no cluster")
    n_workers = None if workers == "auto" else int(workers)
    if is_ray(kind):
        from pytest_ddenv.execution.ray_pool import RayCluster

        return RayCluster(kind, n_workers=n_workers)
    return DaskCluster(None if kind == "dask" else kind, n_workers=n_workers)


def make_pool(
    job: Job,
    workers: int | str = "auto",
    executor: str | None = None,
    *,
    in_process: Handler | None = None,
    cluster: DaskCluster | RayCluster | None = None,
    **options: Any,
) -> Pool[Any]:
    """The pool for `--ddenv-workers` / `--ddenv-executor` (and the `ddenv` command's `--workers`/`--executor`).

    `executor` None (or "local"): `workers` local worker processes serving `job` ('auto': the cores idle
    now, `idle_cores`: a loaded machine gets no more workers than it can run); with 1 worker and an
    `in_process` handler, probes run in this process instead. "dask" / "ray": a local dask / Ray cluster of
    `workers` processes; "tcp://host:port" / "tls://...": a running dask scheduler, "ray://host:port": a
    running Ray cluster (`workers` is then ignored). Pass `cluster` (from `make_cluster`) to reuse a
    connection (it is then not closed with the pool). `options` go to the pool class (watchdog,
    fault_injection, ...). Raises PoolConfigError for invalid values.
    """
    kind = check_executor(executor)
    count = default_workers(workers) if kind is None else resolve_workers(workers)
    if kind is None:
        return LocalPool(job, count, in_process=in_process if count == 1 else None, **options)
    if cluster is None:
        cluster = make_cluster(kind, count)
        owns = True
    else:
        owns = False
    try:
        if isinstance(cluster, DaskCluster):
            return DaskPool(job, cluster, owns_cluster=owns, **options)
        from pytest_ddenv.execution.ray_pool import RayPool

        return RayPool(job, cluster, owns_cluster=owns, **options)
    except BaseException:
        if owns:
            cluster.close()
        raise
