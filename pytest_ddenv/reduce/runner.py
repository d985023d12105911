"""Starting probe attempts: inline or on the executor, within the budget, counted, prefetched ones reused.

Every simulation the engine starts goes through a `Runner`, so `Counters.started` (what the probe budget
counts) is kept in one place: +1 when an attempt is started, -1 when a queued one is cancelled before it ran.
"""

from __future__ import annotations

import concurrent.futures
import functools
import time
from dataclasses import replace
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.budget import Budget, BudgetExhausted
from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.prefetch import Prefetch
from pytest_ddenv.reduce.types import Candidate, Outcome, Probe, ProbeCancelled, ProbeObservation


def call_probe(probe: Probe, candidate: Candidate, attempt: int, counters: Counters | None = None) -> Any:
    """Run one probe; an exception from it becomes an ERROR observation (KeyboardInterrupt and
    ProbeCancelled pass). Counts the simulation in `counters` as it starts."""
    if counters is not None:
        counters.ran()
    started = time.perf_counter()
    try:
        return probe(candidate, attempt)
    except ProbeCancelled:
        raise
    except Exception as error:  # noqa: BLE001 - a probe runs user code: whatever it raises is an ERROR outcome
        return ProbeObservation(
            Outcome.ERROR,
            detail=f"probe raised {type(error).__name__}: {error}",
            wall_time=time.perf_counter() - started,
        )


def checked_observation(value: Any) -> ProbeObservation:
    """The probe's result as an ProbeObservation (an outcome given by its value converted); ReductionError if
    it is not one."""
    if not isinstance(value, ProbeObservation):
        raise ReductionError(f"the probe must return an ProbeObservation, got {type(value).__name__}: {value!r}")
    if not isinstance(value.outcome, Outcome):
        try:
            value = replace(value, outcome=Outcome(value.outcome))
        except ValueError:
            choices = ", ".join(outcome.value for outcome in Outcome)
            raise ReductionError(f"ProbeObservation.outcome must be one of {choices}, got {value.outcome!r}") from None
    return value


class Runner:
    """Starts attempts of candidates: at once in this thread (no executor) or on the executor."""

    def __init__(
        self,
        probe: Probe,
        executor: concurrent.futures.Executor | None,
        workers: int,
        budget: Budget,
        counters: Counters,
    ) -> None:
        self.probe = probe
        self.executor = executor
        self.workers = workers
        """How many probes a round keeps running at once on the executor (the scheduler's window)."""
        self.budget = budget
        self.counters = counters
        self.prefetch = Prefetch()
        """Probes started ahead of need or left over by a decided round (see prefetch.py)."""

    def exhausted(self) -> str | None:
        """Why no simulation may start now (a budget ran out), or None."""
        return self.budget.exhausted(self.counters.started)

    def start(self, candidate: Candidate, attempt: int) -> concurrent.futures.Future[Any]:
        """The future of one attempt: the prefetched one if there is one, else started now (submitted to the
        executor, or without one run here before this returns). Raises BudgetExhausted when the budget
        forbids starting it, or (run here) when the probe was cancelled."""
        future = self.prefetch.take(candidate, attempt)
        if future is not None:
            return future
        reason = self.exhausted()
        if reason is not None:
            raise BudgetExhausted(reason)
        self.counters.started += 1
        if self.executor is not None:
            return self.executor.submit(call_probe, self.probe, candidate, attempt, self.counters)
        future = concurrent.futures.Future()
        try:
            future.set_result(call_probe(self.probe, candidate, attempt, self.counters))
        except ProbeCancelled as cancelled:
            raise self.budget.stop(cancelled.reason) from None
        return future

    def start_ahead(self, candidate: Candidate, attempt: int) -> None:
        """Start one attempt on the executor into the prefetch store (the caller checked the budget)."""
        assert self.executor is not None
        self.counters.started += 1
        submit = functools.partial(self.executor.submit, call_probe, self.probe, candidate, attempt, self.counters)
        self.prefetch.start((frozenset(candidate), attempt), submit)

    def result(self, future: concurrent.futures.Future[Any], timeout: float | None = None) -> ProbeObservation:
        """The checked observation of a started attempt. Raises BudgetExhausted when the probe was cancelled,
        and TimeoutError when `timeout` seconds pass first."""
        try:
            value = future.result(timeout=timeout)
        except ProbeCancelled as cancelled:
            raise self.budget.stop(cancelled.reason) from None
        return checked_observation(value)

    def cancel(self, future: concurrent.futures.Future[Any]) -> bool:
        """Cancel an attempt that has not started yet (it is no simulation then: not counted); False when
        it runs or ran."""
        if future.cancel():
            self.counters.started -= 1
            return True
        return False

    def cancel_prefetched_except(self, wanted: set[frozenset[str]]) -> None:
        """Cancel the queued prefetched attempts of candidates not `wanted` (not counted any more)."""
        self.counters.started -= self.prefetch.cancel_except(wanted)

    def close(self) -> None:
        """Forget the prefetched probes: cancel those not started; the running ones are abandoned."""
        self.prefetch.close()
