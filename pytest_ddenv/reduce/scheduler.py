"""Scheduling one round: which attempts run when, serially or on the executor, for the first reproducing trial.

`Scheduler.first_reproducing(trials)` answers one ddmin round: the first trial, in the given order, whose
candidate reproduces f. With an executor the trials are probed concurrently (each candidate's attempts
stay sequential, exactly as the deflake policy asks for them), and the answer is still the first in
order: a later candidate that reproduces f first in wall time is not taken while an earlier one is
undecided. So, for a probe that is a deterministic function of (candidate, attempt), the result is the
serial one; only counters and the order of log lines differ.

`after_rejection` (the engine's drift watch) is called at the round's first rejection, in trial order, of a
candidate no earlier round consulted (a precondition's skip is none; a verdict an earlier round made or read
costs nothing now), serially and concurrently alike and the same on a resumed log, so it sees the same state
either way; it may raise to end the round.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, Sequence
from typing import Any

from pytest_ddenv.reduce.budget import BudgetExhausted
from pytest_ddenv.reduce.decider import Decider, OpenCandidate, Status
from pytest_ddenv.reduce.deflake import runs_worth_starting_ahead
from pytest_ddenv.reduce.journal import Journal
from pytest_ddenv.reduce.runner import Runner
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Candidate, Decision

Futures = dict[concurrent.futures.Future[Any], tuple[OpenCandidate, int]]
"""The attempts a concurrent round has running: future -> (candidate, attempt)."""


class Scheduler:
    """Runs the attempts that decide a round's trials, in an order that keeps the serial answer."""

    def __init__(
        self,
        decider: Decider,
        journal: Journal,
        runner: Runner,
        lookahead: Callable[[], list[tuple[Candidate, int]]] | None = None,
    ) -> None:
        self.decider = decider
        self.journal = journal
        self.runner = runner
        self.lookahead = lookahead
        """The engine's probes to start next if the current round finds nothing (prefetched on idle workers)."""
        self._ahead: list[tuple[Candidate, int]] | None = None
        self.after_rejection: Callable[[], None] | None = None
        """Called once per round, at its first rejection of a candidate no earlier round consulted."""

    def first_reproducing(self, trials: Sequence[Trial], *, quiet: bool = False) -> tuple[int, Decision] | None:
        """Index and verdict of the first trial that reproduces f, or None if none does.

        `quiet` (the verification pass) does not count or log verdicts already known.
        Raises BudgetExhausted when a budget runs out before the answer is known.
        """
        earlier = set(self.journal.consulted)
        if self.runner.executor is None:
            return self._serial(trials, quiet, earlier)
        return self._concurrent(trials, quiet, earlier)

    def planned(self, trials: Sequence[Trial]) -> list[tuple[Candidate, int]]:
        """The probes deciding `trials` would start first: a first attempt of each undecided candidate, then
        the re-runs a fixed-length deflake rule may need."""
        policy = self.decider.policy
        opened = [status for status in map(self.decider.status, trials) if isinstance(status, OpenCandidate)]
        opened = [state for state in opened if policy.verdict(state.outcomes) is None]
        limit = runs_worth_starting_ahead(policy)
        first = [(state.trial.candidate, len(state.outcomes)) for state in opened]
        later = [(s.trial.candidate, a) for s in opened for a in range(len(s.outcomes) + 1, limit)]
        return first + later

    # -- serially ----------------------------------------------------------------------------------------

    def _serial(self, trials: Sequence[Trial], quiet: bool, earlier: set[frozenset[str]]
                ) -> tuple[int, Decision] | None:
        rejected = False
        for index, trial in enumerate(trials):
            status = self.decider.status(trial)
            if isinstance(status, str):
                self.journal.skip(trial, status, quiet=quiet)
                continue
            if isinstance(status, Decision):
                self.journal.consult(trial, status, cached=True, quiet=quiet)
                decision = status
            else:
                decision = self._decide_serially(status)
                self.journal.consult(trial, decision, cached=False, quiet=quiet)
            if decision.reproduces:
                return index, decision
            if self.after_rejection is not None and not rejected and frozenset(trial.candidate) not in earlier:
                rejected = True
                self.after_rejection()
        return None

    def _decide_serially(self, state: OpenCandidate) -> Decision:
        while (decision := self.decider.settle(state)) is None:
            attempt = len(state.outcomes)
            future = self.runner.start(state.trial.candidate, attempt)
            self.decider.take(state, attempt, self.runner.result(future))
        return decision

    # -- concurrently ------------------------------------------------------------------------------------

    def _concurrent(self, trials: Sequence[Trial], quiet: bool, earlier: set[frozenset[str]]
                    ) -> tuple[int, Decision] | None:
        self.runner.cancel_prefetched_except({frozenset(trial.candidate) for trial in trials})
        self._ahead = None
        statuses: list[Status] = [self.decider.status(trial) for trial in trials]
        for status in statuses:
            if isinstance(status, OpenCandidate):
                self.decider.settle(status)
        futures: Futures = {}
        consulted = 0

        def consult_through(last: int) -> None:
            """The serial loop's skip and consult records of the trials up to `last`, in trial order."""
            nonlocal consulted
            for trial, status in zip(trials[consulted: last + 1], statuses[consulted: last + 1], strict=True):
                if isinstance(status, str):
                    self.journal.skip(trial, status, quiet=quiet)
                else:
                    decision = _decision_of(status)
                    assert decision is not None
                    self.journal.consult(trial, decision, cached=isinstance(status, Decision), quiet=quiet)
            consulted = max(consulted, last + 1)

        finished = False
        try:
            answer = self._run_round(statuses, futures, [frozenset(trial.candidate) in earlier for trial in trials],
                                     consult_through)
            finished = True
        finally:
            self._wind_up(statuses, futures, finished)
        consult_through(len(statuses) - 1 if answer is None else answer)
        if answer is None:
            return None
        decision = _decision_of(statuses[answer])
        assert decision is not None
        return answer, decision

    def _run_round(self, statuses: list[Status], futures: Futures, old: list[bool],
                   consult_through: Callable[[int], None]) -> int | None:
        """Start and collect attempts until the round's answer is known: the first reproducing index or None.
        `old`: which trials an earlier round consulted. Before the drift watch runs at the first new rejection,
        the trials up to it are consulted (`consult_through`) as the serial loop would have by then: the watch
        may end the round, and the learner's history must not depend on the executor."""
        position = {id(status): index for index, status in enumerate(statuses)}
        rejected = False
        while True:
            if not rejected and self.after_rejection is not None \
                    and (first := _first_new_rejection(statuses, old)) is not None:
                rejected = True
                consult_through(first)
                self.after_rejection()
            if (resolution := _resolve(statuses))[0]:
                break
            reason = self._submit(statuses, futures)
            if not futures:
                raise BudgetExhausted(reason or "budget: max_probes")
            done, _ = concurrent.futures.wait(
                futures, timeout=self.runner.budget.seconds_left(), return_when=concurrent.futures.FIRST_COMPLETED
            )
            if not done:  # the time budget ran out while probes run: they are abandoned (see Runner.close())
                raise self.runner.budget.stop("budget: max_seconds")
            for future in sorted(done, key=lambda f: position[id(futures[f][0])]):
                state, attempt = futures.pop(future)
                self._finish(state, attempt, future)
        return resolution[1]

    def _wind_up(self, statuses: Sequence[Status], futures: Futures, finished: bool) -> None:
        """The round is over (answered, or stopped by an exception): cancel the queued attempts, record the
        results already there (when answered) and keep the running ones for later (prefetch store)."""
        for future in list(futures):
            if self.runner.cancel(future):  # queued, never started: not a simulation
                futures.pop(future)
        if finished:  # results that are already there are recorded; the running ones are kept for later
            for future in [f for f in futures if f.done()]:
                state, attempt = futures.pop(future)
                self._finish(state, attempt, future)
        for future, (state, attempt) in futures.items():
            self.runner.prefetch.adopt(state.trial.candidate, attempt, future)
        self.decider.keep_undecided(statuses)

    def _submit(self, statuses: list[Status], futures: Futures) -> str | None:
        """Start attempts of undecided candidates, earliest first, up to the window and budget; the budget's
        reason when it stopped them.

        Only candidates before the first one known to reproduce f can still change the answer. First one
        attempt for each of them with none running; then, while workers are still idle, the later re-runs
        the fixed deflake policy may need (speculatively: results are applied in attempt order and those
        past the verdict are dropped, so the decisions are exactly the serial ones); then, if workers are
        still idle, the engine's next probes (prefetched, see prefetch.py).
        """
        undecided = _undecided(statuses)
        idle = [state for state in undecided if not state.in_flight and not state.early]
        first = [(state, state.next_attempt()) for state in idle]
        limit = runs_worth_starting_ahead(self.decider.policy)
        speculative = [
            (state, attempt)
            for state in undecided
            for attempt in range(state.next_attempt() + any(state is other for other in idle), limit)
        ]
        for state, attempt in first + speculative:
            if len(futures) >= self.runner.workers:
                return None
            if attempt in state.in_flight:
                continue
            try:
                future = self.runner.start(state.trial.candidate, attempt)
            except BudgetExhausted as exhausted:
                return exhausted.reason
            state.in_flight.add(attempt)
            futures[future] = (state, attempt)
        self._prefetch_ahead(statuses, busy=len(futures))
        return None

    def _prefetch_ahead(self, statuses: Sequence[Status], busy: int) -> None:
        """Start the engine's next probes on the workers this round leaves idle (never past the budget)."""
        runner = self.runner
        if self.lookahead is None or busy + runner.prefetch.running() >= runner.workers:
            return
        if self._ahead is None:
            self._ahead = self.lookahead()
        in_round = {frozenset(status.trial.candidate) for status in statuses if isinstance(status, OpenCandidate)}
        for candidate, attempt in self._ahead:
            key = (frozenset(candidate), attempt)
            if key in runner.prefetch or key[0] in in_round:
                continue
            if busy + runner.prefetch.running() >= runner.workers or runner.exhausted():
                return
            runner.start_ahead(candidate, attempt)

    def _finish(self, state: OpenCandidate, attempt: int, future: concurrent.futures.Future[Any]) -> None:
        state.in_flight.discard(attempt)
        late = self.decider.observe(state, attempt, self.runner.result(future))
        for later, observation in late.items():  # re-runs past the verdict: kept for the failure-rate runs
            self.runner.prefetch.keep(state.trial.candidate, later, observation)


def _decision_of(status: Status) -> Decision | None:
    """The verdict of a status, if it has one (None: skipped, or still open)."""
    if isinstance(status, Decision):
        return status
    return status.decision if isinstance(status, OpenCandidate) else None


def _undecided(statuses: Sequence[Status]) -> list[OpenCandidate]:
    """Open, undecided candidates before the first one known to reproduce f."""
    undecided: list[OpenCandidate] = []
    for status in statuses:
        decision = _decision_of(status)
        if decision is not None and decision.reproduces:
            break
        if isinstance(status, OpenCandidate) and status.decision is None:
            undecided.append(status)
    return undecided


def _first_new_rejection(statuses: Sequence[Status], old: Sequence[bool]) -> int | None:
    """The index of the serial loop's first rejection of a trial no earlier round consulted, if the loop would
    reach it now (every trial before it skipped or rejected, it decided and rejected); else None."""
    for index, (status, consulted) in enumerate(zip(statuses, old, strict=True)):
        if isinstance(status, str):
            continue
        decision = _decision_of(status)
        if decision is None or decision.reproduces:
            return None
        if not consulted:
            return index
    return None


def _resolve(statuses: Sequence[Status]) -> tuple[bool, int | None]:
    """(known, index): is the round's answer known yet, and the first reproducing index (or None)."""
    for index, status in enumerate(statuses):
        if isinstance(status, str):
            continue
        decision = _decision_of(status)
        if decision is None:
            return False, None
        if decision.reproduces:
            return True, index
    return True, None
