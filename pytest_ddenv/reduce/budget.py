"""Budgets: whether a reduction may still start a simulation (probe count, wall time, a cancelled probe), and
the stages' share of the driver's count (`StageBudget`)."""

from __future__ import annotations

import time
from collections.abc import Callable
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


@dataclass
class StageBudget:
    """The simulations the stages after the models may still start: `limit` (None: no limit) minus what
    `started()` counts (the driver's count of every simulation of this reduction) since `begin`. Each engine
    call of a stage gets what is `left` as its `Budget.max_probes`."""

    limit: int | None
    started: Callable[[], int]
    begin: int = 0
    per_stage: int | None = None
    reserve: int = 0
    """Simulations kept for what comes later (the final world's failure rate, the passing world)."""
    share: int | None = None
    """The most the current stage may start (its fair share of what is left), None: no share."""
    decisions: int = 0
    """Worlds decided so far by the stages (the engine's decided candidates and single decisions made
    here; not the failure-rate runs): the stages' "probes", comparable with the model-level probes."""

    def left(self, stage_begin: int | None = None) -> int | None:
        spent = self.started() - self.begin
        left = None if self.limit is None else max(0, self.limit - self.reserve - spent)
        for cap in (self.per_stage, self.share):
            if cap is not None and stage_begin is not None:
                stage_left = max(0, cap - (self.started() - stage_begin))
                left = stage_left if left is None else min(left, stage_left)
        return left
