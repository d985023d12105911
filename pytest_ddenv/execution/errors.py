"""Errors of the execution layer (all `DdenvError`s, so a probe classifies them as ERROR, never as a verdict)."""

from __future__ import annotations

from pytest_ddenv.errors import DdenvError


class WorkerError(DdenvError):
    """The pool could not complete a probe: its worker died twice, hung past the watchdog, the pool was
    closed while it ran, or the distributed cluster lost it. Never the failure being reproduced."""


class WorkerStartError(WorkerError):
    """A worker could not start serving its job: the test module (or the user code it imports) does not
    import in a fresh process, the test is not collected there, or the worker died while starting. The
    message carries the worker's own error and traceback."""


class PoolConfigError(DdenvError):
    """A pool was asked for with invalid settings (worker count, executor address, fault specification)."""


class ProbeDeadline(WorkerError):
    """The probe was stopped at its caller's deadline (`call(..., timeout=...)`: the end of a reduction's time
    budget), not because it hung. Not an outcome of the test."""
