"""Budgets: whether a reduction may still start a simulation (probe count, wall time, a cancelled probe)."""

from __future__ import annotations

import time
from dataclasses import dataclass


class BudgetExhausted(Exception):
    """Internal: a budget ran out before the round could be decided."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass
class Budget:
    """`max_probes` bounds every simulation the engine starts (calibration, reduction, speculative,
    prefetched and failure-rate runs); `max_seconds` the wall time, also while probes run. A probe that its
    caller cancelled (`ProbeCancelled`) stops the reduction for the reason it gives."""

    max_probes: int | None
    max_seconds: float | None
    started_at: float
    stopped: str | None = None

    def stop(self, reason: str) -> BudgetExhausted:
        self.stopped = self.stopped or reason
        return BudgetExhausted(self.stopped)

    def exhausted(self, probes_started: int) -> str | None:
        if self.stopped is not None:
            return self.stopped
        if self.max_probes is not None and probes_started >= self.max_probes:
            return "budget: max_probes"
        if self.max_seconds is not None and time.monotonic() - self.started_at >= self.max_seconds:
            return "budget: max_seconds"
        return None

    def seconds_left(self) -> float | None:
        """Wall seconds until the time budget runs out (None: no time budget)."""
        if self.max_seconds is None:
            return None
        return max(0.0, self.started_at + self.max_seconds - time.monotonic())
