"""Deciding candidates for the engine: its parts, wired together (`probing`); the engine calls each part.

decider.py decides a candidate from its attempts' outcomes (cache, preconditions, deflake policy);
scheduler.py runs a round's attempts (serially, or concurrently on an executor, with speculation and
prefetching) for the first reproducing trial; extra_runs.py runs a decided world's failure-rate and
calibration attempts; runner.py starts attempts within the budget (budget.py) and counts them (counters.py);
journal.py writes the records of all this to the run log.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, MutableMapping
from dataclasses import dataclass
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
from pytest_ddenv.reduce.types import Candidate, Outcome, Precondition, Probe


@dataclass(frozen=True)
class Probing:
    """The parts that decide candidates and keep the books (counters, cache, log, learner history):
    `decider` (a candidate's verdict from its runs' outcomes; its `policy` is the deflake rule, which the
    engine sets after calibrating deflake="auto"), `scheduler` (a round's runs, for the first reproducing
    trial), `extra_runs` (failure-rate and calibration runs), `runner` (starts runs within the `budget`)."""

    budget: Budget
    counters: Counters
    preconditions: tuple[Precondition, ...]
    decider: Decider
    runner: Runner
    scheduler: Scheduler
    extra_runs: ExtraRuns


def probing(
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
) -> Probing:
    """The parts, wired. `workers`: how many probes a round keeps running at once on `executor`.
    `lookahead`: the probes the engine will start next if the current round finds nothing (started early on
    idle workers)."""
    counters = Counters()
    journal = Journal(log, elapsed, counters, context, keep)
    decider = Decider(policy=policy, preconditions=preconditions, cache=cache, preloaded=preloaded,
                      journal=journal, counters=counters, on_probe=on_probe)
    runner = Runner(probe, executor, workers, budget, counters)
    return Probing(budget, counters, preconditions, decider, runner,
                   Scheduler(decider, journal, runner, lookahead), ExtraRuns(runner, journal))
