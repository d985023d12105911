"""Errors of the execution layer (both are `DdenvError`s, so a probe classifies them as ERROR)."""

from __future__ import annotations

from pytest_ddenv.errors import DdenvError


class SimulationError(DdenvError):
    """A simulation could not be completed by the pool: its worker died twice, hung past the watchdog, the
    pool was closed while it ran, or the distributed cluster lost it. Never the failure being reproduced."""


class PoolConfigError(DdenvError):
    """A pool was asked for with invalid settings (worker count, executor address, fault specification)."""
