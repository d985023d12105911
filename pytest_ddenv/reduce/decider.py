"""Deciding candidates: from the outcomes of a candidate's attempts, in attempt order, to its verdict.

A candidate's status is a precondition's skip reason, a verdict already known (cache, or an errored
rejection of this reduction), or an `OpenCandidate` that collects outcomes until the deflake policy gives
a verdict. Verdicts go to the cache; a rejection resting on ERROR runs alone stays out of it (see
Decision.errored). Which attempts run, and when, is the scheduler's business (scheduler.py).
"""

from __future__ import annotations

from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pytest_ddenv.reduce.counters import Counters
from pytest_ddenv.reduce.deflake import DeflakePolicy
from pytest_ddenv.reduce.journal import Journal
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Candidate, Decision, Outcome, Precondition, ProbeObservation, Trace


@dataclass
class OpenCandidate:
    """A candidate being decided: its outcomes so far (attempt i = outcomes[i])."""

    trial: Trial
    outcomes: list[Outcome]
    trace: Trace | None = None
    in_flight: set[int] = field(default_factory=set)
    """Attempts running now."""
    early: dict[int, ProbeObservation] = field(default_factory=dict)
    """Results of speculative attempts that arrived before an earlier attempt's (applied in attempt order)."""
    decision: Decision | None = None

    def next_attempt(self) -> int:
        return max([len(self.outcomes) - 1, *self.in_flight, *self.early]) + 1


Status = str | Decision | OpenCandidate
"""A trial's status in a round: a precondition's skip reason, a known verdict, or an open candidate."""


class Decider:
    """Decides candidates by the deflake policy and remembers the verdicts (cache, errored rejections)."""

    def __init__(
        self,
        *,
        policy: DeflakePolicy,
        preconditions: tuple[Precondition, ...],
        cache: MutableMapping[Any, Any],
        preloaded: dict[frozenset[str], list[Outcome]],
        journal: Journal,
        counters: Counters,
        on_probe: Callable[[Candidate, Outcome], None],
    ) -> None:
        self.policy = policy
        self.preconditions = preconditions
        self.cache = cache
        self.preloaded = preloaded
        """Outcomes of candidates a resumed log left undecided (and of errored ones being retried)."""
        self.journal = journal
        self.counters = counters
        self.on_probe = on_probe
        self.errored: dict[frozenset[str], Decision] = {}
        """Rejections that rest on ERROR runs: "not f" for this reduction, never cached (see Decision.errored)."""
        self._errored_runs: dict[frozenset[str], list[Outcome]] = {}
        self._retried: set[frozenset[str]] = set()
        self._left_open: dict[frozenset[str], OpenCandidate] = {}
        """Candidates a round left undecided, with their runs so far (see keep_undecided)."""

    def status(self, trial: Trial) -> Status:
        """A skip reason, a known verdict, or an open candidate (with runs already logged, when resuming)."""
        for check in self.preconditions:
            reason = check(trial.candidate)
            if reason is not None:
                return str(reason)
        key = frozenset(trial.candidate)
        known = self.cache.get(key)
        if isinstance(known, Decision):
            return known
        if key in self.errored:
            return self.errored[key]
        earlier = self._left_open.get(key)
        if earlier is not None:  # running attempts were handed to the prefetch store, which gives them back
            done = len(earlier.outcomes)
            early = {attempt: result for attempt, result in earlier.early.items() if attempt >= done}
            return OpenCandidate(trial, list(earlier.outcomes), earlier.trace, early=early)
        return OpenCandidate(trial, list(self.preloaded.get(key, ())))

    def take(self, state: OpenCandidate, attempt: int, observation: ProbeObservation) -> None:
        """Apply the next attempt's result (attempt == len(state.outcomes)): counted, logged, reported."""
        self.counters.probes += 1
        state.outcomes.append(observation.outcome)
        if observation.outcome is Outcome.FAIL and state.trace is None:
            state.trace = observation.trace
        self.journal.probe(state.trial, attempt, observation, purpose="reduce")
        self.on_probe(state.trial.candidate, observation.outcome)

    def settle(self, state: OpenCandidate) -> Decision | None:
        """Decide `state` if the policy has a verdict on its outcomes so far; the decision, or None."""
        verdict = self.policy.verdict(state.outcomes)
        return None if verdict is None else self._decide(state, verdict)

    def observe(self, state: OpenCandidate, attempt: int, observation: ProbeObservation) -> dict[int, ProbeObservation]:
        """Apply an attempt's result that may arrive out of order: results are applied in attempt order
        (later ones wait in `state.early`) until the verdict. Once decided, returns the results that came
        past the verdict (and forgets them); else an empty dict."""
        state.early[attempt] = observation
        while state.decision is None and len(state.outcomes) in state.early:
            current = len(state.outcomes)
            self.take(state, current, state.early.pop(current))
            self.settle(state)
        if state.decision is None:
            return {}
        late = dict(state.early)
        state.early.clear()
        return late

    def keep_undecided(self, statuses: Sequence[Status]) -> None:
        """Candidates the round left undecided keep their runs (outcomes, trace, early results), so a later
        round that needs one again (after a back-off, say) goes on from them instead of simulating again."""
        for status in statuses:
            if isinstance(status, OpenCandidate) and status.decision is None and (status.outcomes or status.early):
                self._left_open[frozenset(status.trial.candidate)] = status

    def errored_among(self, trials: Sequence[Trial]) -> list[Trial]:
        """The trials whose current "not f" rests on ERROR runs alone."""
        return [trial for trial in trials if frozenset(trial.candidate) in self.errored]

    def retry_errored(self, trials: Sequence[Trial]) -> int:
        """Forget the errored rejections of `trials` not retried yet, so that deciding them runs their ERROR
        attempts again (once per candidate); how many will be retried."""
        count = 0
        for trial in trials:
            key = frozenset(trial.candidate)
            if key in self.errored and key not in self._retried:
                self._retried.add(key)
                del self.errored[key]
                runs = self._errored_runs.pop(key, [])
                prefix = runs[: runs.index(Outcome.ERROR)] if Outcome.ERROR in runs else runs
                self.preloaded[key] = prefix
                count += 1
        return count

    def _decide(self, state: OpenCandidate, verdict: bool) -> Decision:
        fails = sum(1 for outcome in state.outcomes if outcome is Outcome.FAIL)
        errors = sum(1 for outcome in state.outcomes if outcome is Outcome.ERROR)
        valid = [outcome for outcome in state.outcomes if outcome is not Outcome.ERROR]
        errored = not verdict and errors > 0 and self.policy.verdict(valid) is not False
        decision = Decision(reproduces=verdict, fails=fails, runs=len(state.outcomes), trace=state.trace,
                            errors=errors, errored=errored)
        state.decision = decision
        key = frozenset(state.trial.candidate)
        if errored:  # not a verdict: "not f" for this reduction only, tried again on resume
            self.errored[key] = decision
            self._errored_runs[key] = list(state.outcomes)
            self.counters.errored.add(key)
        else:
            self.cache[key] = decision
        self.journal.verdict(state.trial, decision, errors)
        return decision
