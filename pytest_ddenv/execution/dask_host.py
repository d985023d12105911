"""What runs on the dask workers (imported there by name: pytest-ddenv must be installed on every worker).

The dask task `run_probe_task` runs a probe on a probe process of this dask worker process (`probe_host.py`:
started on the first probe of a job and kept, under the watchdog, replaced and its probe retried once when it
dies); every dask worker process has one `JobHost`, closed at its exit.
"""

from __future__ import annotations

import atexit

from pytest_ddenv.execution.errors import WorkerStartError
from pytest_ddenv.execution.probe_host import JOBS_KEPT, HostedJob, JobHost, TaskReply, worker_versions
from pytest_ddenv.execution.request import FaultKind, Job, ProbeRequest

_jobs = JobHost("dask worker")


def run_probe_task(job: Job, request: ProbeRequest, retry_fault: FaultKind | None, limit: float | None,
                   by_deadline: bool) -> TaskReply:
    """Runs on a dask worker: the probe on a probe process of `job` (`JobHost.run`).
    Raises `WorkerStartError` when the job cannot start there."""
    return _jobs.run(job, request, retry_fault, limit, by_deadline)


def hosted_jobs() -> JobHost:
    """The jobs this dask worker process hosts."""
    return _jobs


def close_hosted_jobs() -> None:
    """Stop every probe process of this dask worker (at its exit; callable by hand)."""
    _jobs.close()


atexit.register(close_hosted_jobs)


__all__ = ["JOBS_KEPT", "HostedJob", "TaskReply", "WorkerStartError", "close_hosted_jobs", "hosted_jobs",
           "run_probe_task", "worker_versions"]
