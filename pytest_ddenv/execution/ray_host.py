"""What runs on the Ray workers (pytest-ddenv must be installed there): `ProbeSlot`, one actor per probe
that can run at once. An actor is a process of its own that lives as long as the session's connection; it
hosts the probe processes of its most recent jobs (`probe_host.JobHost`: the job's `serve` in the main
thread of a probe process, started on its first probe and kept, under the watchdog, replaced and its probe
retried once when it dies)."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from pytest_ddenv.execution.probe_host import JobHost, TaskReply, worker_versions
from pytest_ddenv.execution.request import FaultKind, Job, ProbeRequest


class ProbeSlot:
    """A Ray actor (`ray.remote(ProbeSlot)`) that runs one probe at a time. `sys_path`: entries added to
    its `sys.path` before any job arrives (a local cluster gets the session's own, so that what the
    session imports, e.g. a test module defining a job, unpickles there)."""

    def __init__(self, sys_path: Sequence[str] = ()) -> None:
        sys.path.extend(entry for entry in sys_path if entry not in sys.path)
        self._jobs = JobHost("ray actor")

    def probe(self, job: Job, request: ProbeRequest, retry_fault: FaultKind | None, limit: float | None,
              by_deadline: bool) -> TaskReply:
        return self._jobs.run(job, request, retry_fault, limit, by_deadline)

    def versions(self) -> dict[str, str]:
        return worker_versions()

    def pid(self) -> int:
        return os.getpid()

    def close(self) -> None:
        self._jobs.close()
