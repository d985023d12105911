"""The journal of deciding candidates: probe, verdict, cache-hit and skip records, counted and in the run log.

It also keeps the learner's history (`Context.history`): each candidate's verdict once, when the serial
algorithm looks at it (`consult`), so that the learner sees the same history with or without an executor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Decision, Outcome, ProbeObservation


@dataclass
class Journal:
    """Writes what deciding candidates did to the run log (time-stamped), counts it, feeds the learner."""

    log: ProbeLog | None
    elapsed: Callable[[], float]
    counters: Counters
    context: Context
    keep: frozenset[str]
    consulted: set[frozenset[str]] = field(default_factory=set, init=False)
    """The candidates whose verdict the serial algorithm has looked at (`consult`)."""

    def probe(self, trial: Trial, attempt: int, observation: ProbeObservation, *, purpose: str) -> None:
        """One probe whose result is used ("reduce", "calibration" or "failure-rate")."""
        if observation.outcome is Outcome.ERROR:
            self.counters.errors += 1
        self.write(events.Probe(purpose=purpose, kind=trial.kind, candidate=tuple(trial.candidate),
                                size=len(trial.candidate), attempt=attempt, seed=observation.seed,
                                outcome=observation.outcome.value, signature=observation.signature,
                                sim_time=observation.sim_time, wall_time=observation.wall_time,
                                detail=observation.detail))

    def verdict(self, trial: Trial, decision: Decision, errors: int) -> None:
        """A candidate just decided, on runs of which `errors` were ERROR."""
        kind = events.Errored if decision.errored else events.Accept if decision.reproduces else events.Reject
        event = _decision(kind, trial, decision, errors=errors or None)
        if isinstance(event, events.Accept) and decision.trace is not None:
            event = replace(event, trace=decision.trace.to_json())
        self.write(event)

    def consult(self, trial: Trial, decision: Decision, *, cached: bool, quiet: bool) -> None:
        """The serial algorithm looks at this verdict now: feed the learner, count and log cache hits."""
        key = frozenset(trial.candidate)
        if key not in self.consulted:
            self.consulted.add(key)
            self.context.history.append(Verdict(frozenset(key - self.keep), decision.reproduces, decision.errored))
        if cached and not quiet:
            self.counters.cache_hits += 1
            self.write(_decision(events.CacheHit, trial, decision, errored=decision.errored or None))

    def skip(self, trial: Trial, reason: str, *, quiet: bool) -> None:
        """The serial algorithm looks at a candidate a precondition refused (logged once when `quiet`)."""
        key = frozenset(trial.candidate)
        first_time = key not in self.counters.skipped
        self.counters.skipped.add(key)
        if first_time or not quiet:
            self.write(events.Skip(kind=trial.kind, candidate=tuple(trial.candidate), size=len(trial.candidate),
                                   reason=reason))

    def write(self, event: events.Event) -> None:
        if self.log is not None:
            self.log.write(replace(event, elapsed=round(self.elapsed(), 6)))


def _decision(kind: type[events.Decided], trial: Trial, decision: Decision, *, errors: int | None = None,
              errored: bool | None = None) -> events.Decided:
    """The log event of a decision about `trial` (a verdict, or a verdict looked up again)."""
    return kind(kind=trial.kind, candidate=tuple(trial.candidate), size=len(trial.candidate),
                reproduces=decision.reproduces, fails=decision.fails, runs=decision.runs, errors=errors,
                errored=errored)
