"""Extra runs of a decided world: its failure-rate and calibration attempts, within the budget, logged.

Attempts already known (logged by an earlier run of a resumed reduction) are not simulated again; those a
round started ahead of need (prefetch store) are taken from it. With an executor they all run at once.
"""

from __future__ import annotations

import concurrent.futures
from typing import Any

from pytest_ddenv.reduce.budget import BudgetExhausted
from pytest_ddenv.reduce.journal import Journal
from pytest_ddenv.reduce.runner import Runner
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Candidate, Outcome, ProbeObservation

Started = list[tuple[int, concurrent.futures.Future[Any]]]
"""Attempts started for a measurement, in attempt order: (attempt, future)."""


class ExtraRuns:
    """Runs and counts a world's extra attempts (after those that decided it) for the engine."""

    def __init__(self, runner: Runner, journal: Journal) -> None:
        self.runner = runner
        self.journal = journal

    def measure(
        self,
        candidate: Candidate,
        first_attempt: int,
        runs: int,
        purpose: str = "failure-rate",
        *,
        known: dict[int, Outcome] | None = None,
        strict: bool = False,
        into: dict[int, Outcome] | None = None,
    ) -> tuple[int, int]:
        """(fails, runs) over attempts first_attempt .. first_attempt+runs-1, logged with `purpose`
        ("failure-rate" or "calibration"). Attempts in `known` (logged by an earlier run) are not simulated
        again. The budget applies: when it runs out, fewer runs are counted, or with `strict`,
        BudgetExhausted is raised. Calibration runs count as decided probes. `into`, when given, receives
        attempt -> outcome of every attempt counted (known ones included)."""
        attempts = list(range(first_attempt, first_attempt + runs))
        known = known or {}
        submitted, exhausted = self._start(candidate, [attempt for attempt in attempts if attempt not in known])
        results, exhausted = self._collect(candidate, submitted, exhausted)
        fails = done = 0
        for attempt in attempts:
            if attempt in known:
                outcome = known[attempt]
            elif attempt in results:
                observation = results[attempt]
                self.journal.probe(Trial(candidate, purpose), attempt, observation, purpose=purpose)
                if purpose == "calibration":
                    self.runner.counters.probes += 1
                outcome = observation.outcome
            else:
                continue
            if into is not None:
                into[attempt] = outcome
            fails += outcome is Outcome.FAIL
            done += 1
        if exhausted is not None and strict:
            raise BudgetExhausted(exhausted)
        return fails, done

    def _start(self, candidate: Candidate, attempts: list[int]) -> tuple[Started, str | None]:
        """Start `attempts` in order until the budget stops them: those started, and the budget's reason."""
        started: Started = []
        for attempt in attempts:
            try:
                started.append((attempt, self.runner.start(candidate, attempt)))
            except BudgetExhausted as exhausted:
                return started, exhausted.reason
        return started, None

    def _collect(
        self, candidate: Candidate, started: Started, exhausted: str | None
    ) -> tuple[dict[int, ProbeObservation], str | None]:
        """Wait for the started attempts' results (not past the time budget); the results by attempt and why
        the budget stopped the measurement (None: it did not)."""
        results: dict[int, ProbeObservation] = {}
        stopped = exhausted is not None and exhausted != "budget: max_probes"  # time is up: wait for nothing more
        try:
            for attempt, future in started:
                if stopped and self.runner.cancel(future):
                    continue
                try:
                    results[attempt] = self.runner.result(future, timeout=self.runner.budget.seconds_left())
                except BudgetExhausted as cancelled:
                    exhausted, stopped = cancelled.reason, True
                except concurrent.futures.TimeoutError:
                    exhausted, stopped = self.runner.budget.stop("budget: max_seconds").reason, True
                    self.runner.prefetch.adopt(candidate, attempt, future)  # abandoned (see Runner.close())
        finally:
            for attempt, future in started:
                if attempt not in results and not future.done():
                    self.runner.cancel(future)
        return results, exhausted
