"""Deciding candidates for the engine: one facade over the decider, scheduler, extra runs and journal.

decider.py decides a candidate from its attempts' outcomes (cache, preconditions, deflake policy);
scheduler.py runs a round's attempts (serially, or concurrently on an executor, with speculation and
prefetching) for the first reproducing trial; extra_runs.py runs a decided world's failure-rate and
calibration attempts; runner.py starts attempts within the budget (budget.py) and counts them (counters.py);
journal.py writes the records of all this to the run log.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, MutableMapping, Sequence
from typing import Any

from pytest_ddenv.reduce.budget import Budget
from pytest_ddenv.reduce.context import Context
from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.decider import Decider
from pytest_ddenv.reduce.deflake import DeflakePolicy
from pytest_ddenv.reduce.extra_runs import ExtraRuns
from pytest_ddenv.reduce.journal import Journal
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.runner import Runner
from pytest_ddenv.reduce.scheduler import Scheduler
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Candidate, Decision, Outcome, Precondition, Probe


class Prober:
    """Decides candidates for the engine and keeps the books (counters, cache, log, learner history)."""

    def __init__(
        self,
        *,
        probe: Probe,
        policy: DeflakePolicy,
        keep: frozenset[str],
        preconditions: tuple[Precondition, ...],
        cache: MutableMapping[Any, Any],
        preloaded: dict[frozenset[str], list[Outcome]],
        budget: Budget,
        executor: concurrent.futures.Executor | None,
        workers: int,
        log: ProbeLog | None,
        context: Context,
        elapsed: Callable[[], float],
        on_probe: Callable[[Candidate, Outcome], None],
        lookahead: Callable[[], list[tuple[Candidate, int]]] | None = None,
    ) -> None:
        """`workers`: how many probes a round keeps running at once on `executor`. `lookahead`: the probes
        the engine will start next if the current round finds nothing (started early on idle workers)."""
        self.budget = budget
        self.counters = Counters()
        self.preconditions = preconditions
        journal = Journal(log, elapsed, self.counters, context, keep)
        self.decider = Decider(policy=policy, preconditions=preconditions, cache=cache, preloaded=preloaded,
                               journal=journal, counters=self.counters, on_probe=on_probe)
        self.runner = Runner(probe, executor, workers, budget, self.counters)
        self.scheduler = Scheduler(self.decider, journal, self.runner, lookahead)
        self.extra_runs = ExtraRuns(self.runner, journal)
        self.measure = self.extra_runs.measure
        """A decided world's failure-rate and calibration runs (`ExtraRuns.measure`)."""

    @property
    def policy(self) -> DeflakePolicy:
        """The deflake rule deciding candidates (the engine sets it after calibrating deflake="auto")."""
        return self.decider.policy

    @policy.setter
    def policy(self, policy: DeflakePolicy) -> None:
        self.decider.policy = policy

    def first_reproducing(self, trials: Sequence[Trial], *, quiet: bool = False) -> tuple[int, Decision] | None:
        """See Scheduler.first_reproducing."""
        return self.scheduler.first_reproducing(trials, quiet=quiet)

    def planned(self, trials: Sequence[Trial]) -> list[tuple[Candidate, int]]:
        """See Scheduler.planned."""
        return self.scheduler.planned(trials)


    def errored_among(self, trials: Sequence[Trial]) -> list[Trial]:
        """See Decider.errored_among."""
        return self.decider.errored_among(trials)

    def retry_errored(self, trials: Sequence[Trial]) -> int:
        """See Decider.retry_errored."""
        return self.decider.retry_errored(trials)

    def exhausted(self) -> str | None:
        """Why no simulation may start now (a budget ran out), or None."""
        return self.runner.exhausted()

    def close(self) -> None:
        """Forget the prefetched probes: cancel those not started; the running ones are abandoned."""
        self.runner.close()
