"""The journal of deciding candidates: probe, verdict, cache-hit and skip records, counted and in the run log.

It also keeps the learner's history (`Context.history`): each candidate's verdict once, when the serial
algorithm looks at it (`consult`), so that the learner sees the same history with or without an executor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Decision, Outcome, ProbeObservation


class Journal:
    """Writes what deciding candidates did to the run log (time-stamped), counts it, feeds the learner."""

    def __init__(
        self,
        log: ProbeLog | None,
        elapsed: Callable[[], float],
        counters: Counters,
        context: Context,
        keep: frozenset[str],
    ) -> None:
        self.log = log
        self.elapsed = elapsed
        self.counters = counters
        self.context = context
        self.keep = keep
        self._consulted: set[frozenset[str]] = set()

    def probe(self, trial: Trial, attempt: int, observation: ProbeObservation, *, purpose: str) -> None:
        """One probe whose result is used ("reduce", "calibration" or "failure-rate")."""
        if observation.outcome is Outcome.ERROR:
            self.counters.errors += 1
        self.write(
            {
                "event": "probe",
                "purpose": purpose,
                "kind": trial.kind,
                "candidate": list(trial.candidate),
                "size": len(trial.candidate),
                "attempt": attempt,
                "seed": observation.seed,
                "outcome": observation.outcome.value,
                "signature": observation.signature,
                "sim_time": observation.sim_time,
                "wall_time": observation.wall_time,
                "detail": observation.detail,
            }
        )

    def verdict(self, trial: Trial, decision: Decision, errors: int) -> None:
        """A candidate just decided, on runs of which `errors` were ERROR."""
        record = _decision_record("errored" if decision.errored else "accept" if decision.reproduces else "reject",
                                  trial, decision)
        if errors:
            record["errors"] = errors
        self.write(record)

    def consult(self, trial: Trial, decision: Decision, *, cached: bool, quiet: bool) -> None:
        """The serial algorithm looks at this verdict now: feed the learner, count and log cache hits."""
        key = frozenset(trial.candidate)
        if key not in self._consulted:
            self._consulted.add(key)
            self.context.history.append(Verdict(frozenset(key - self.keep), decision.reproduces))
        if cached and not quiet:
            self.counters.cache_hits += 1
            record = _decision_record("cache-hit", trial, decision)
            if decision.errored:
                record["errored"] = True
            self.write(record)

    def skip(self, trial: Trial, reason: str, *, quiet: bool) -> None:
        """The serial algorithm looks at a candidate a precondition refused (logged once when `quiet`)."""
        key = frozenset(trial.candidate)
        first_time = key not in self.counters.skipped
        self.counters.skipped.add(key)
        if first_time or not quiet:
            self.write(
                {
                    "event": "skip",
                    "kind": trial.kind,
                    "candidate": list(trial.candidate),
                    "size": len(trial.candidate),
                    "reason": reason,
                }
            )

    def write(self, record: dict[str, Any]) -> None:
        if self.log is not None:
            record["elapsed"] = round(self.elapsed(), 6)
            self.log.write(record)


def _decision_record(event: str, trial: Trial, decision: Decision) -> dict[str, Any]:
    """The log record of a decision about `trial` (a verdict, or a verdict looked up again)."""
    return {"event": event, "kind": trial.kind, "candidate": list(trial.candidate), "size": len(trial.candidate),
            "reproduces": decision.reproduces, "fails": decision.fails, "runs": decision.runs}
