"""Deciding candidates: preconditions, cache, deflaked probing, budgets, serial or on an executor.

`Prober.first_reproducing(trials)` answers one ddmin round: the first trial, in the given order, whose
candidate reproduces f. With an executor the trials are probed concurrently (each candidate's attempts
stay sequential, exactly as the deflake policy asks for them), and the answer is still the first in
order: a later candidate that reproduces f first in wall time is not taken while an earlier one is
undecided. So, for a probe that is a deterministic function of (candidate, attempt), the result is the
serial one; only counters and the order of log lines differ.
"""

from __future__ import annotations

import concurrent.futures
import functools
import os
import threading
import time
from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.deflake import DeflakePolicy, runs_worth_starting_ahead
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.prefetch import Prefetch
from pytest_ddenv.reduce.types import (
    Candidate,
    Decision,
    Observation,
    Outcome,
    Precondition,
    Probe,
    ProbeCancelled,
    Trace,
)


class BudgetExhausted(Exception):
    """Internal: a budget ran out before the round could be decided."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class Trial:
    """One candidate of a round and why it is tried ("subset", "complement" or "verify")."""

    candidate: Candidate
    kind: str


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
class _Open:
    """A candidate being decided: its outcomes so far (attempt i = outcomes[i])."""

    trial: Trial
    outcomes: list[Outcome]
    trace: Trace | None = None
    in_flight: set[int] = field(default_factory=set)
    """Attempts running now."""
    early: dict[int, Observation] = field(default_factory=dict)
    """Results of speculative attempts that arrived before an earlier attempt's (applied in attempt order)."""
    decision: Decision | None = None

    def next_attempt(self) -> int:
        return max([len(self.outcomes) - 1, *self.in_flight, *self.early]) + 1


@dataclass
class Counters:
    probes: int = 0
    """Probes decided: results used for a verdict (reduction and calibration runs) in this call."""
    started: int = 0
    """Simulations submitted (every kind); the probe budget counts these."""
    cache_hits: int = 0
    errors: int = 0
    abandoned: int = 0
    """Concurrent or prefetched probes whose results were not needed (still running or thrown away)."""
    skipped: set[frozenset[str]] = field(default_factory=set)
    errored: set[frozenset[str]] = field(default_factory=set)
    """Candidates rejected on ERROR runs alone (see Decision.errored)."""
    _ran: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def ran(self) -> None:
        with self._lock:
            self._ran += 1

    @property
    def simulations(self) -> int:
        """Simulations that actually started (cancelled-before-start submissions excluded)."""
        with self._lock:
            return self._ran


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
        return Observation(
            Outcome.ERROR,
            detail=f"probe raised {type(error).__name__}: {error}",
            wall_time=time.perf_counter() - started,
        )


def checked_observation(value: Any) -> Observation:
    if not isinstance(value, Observation):
        raise ReductionError(f"the probe must return an Observation, got {type(value).__name__}: {value!r}")
    if not isinstance(value.outcome, Outcome):
        try:
            value = replace(value, outcome=Outcome(value.outcome))
        except ValueError:
            choices = ", ".join(outcome.value for outcome in Outcome)
            raise ReductionError(f"Observation.outcome must be one of {choices}, got {value.outcome!r}") from None
    return value


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
        log: ProbeLog | None,
        context: Context,
        elapsed: Callable[[], float],
        on_probe: Callable[[Candidate, Outcome], None],
    ) -> None:
        self.probe = probe
        self.policy = policy
        self.keep = keep
        self.preconditions = preconditions
        self.cache = cache
        self.preloaded = preloaded
        self._left_open: dict[frozenset[str], _Open] = {}
        """Candidates a round left undecided, with their runs so far (see _keep_undecided)."""
        self.budget = budget
        self.executor = executor
        self.log = log
        self.context = context
        self.elapsed = elapsed
        self.on_probe = on_probe
        self.counters = Counters()
        self.errored: dict[frozenset[str], Decision] = {}
        """Rejections that rest on ERROR runs: "not f" for this reduction, never cached (see Decision.errored)."""
        self._errored_runs: dict[frozenset[str], list[Outcome]] = {}
        self._retried: set[frozenset[str]] = set()
        self._consulted: set[frozenset[str]] = set()
        workers = getattr(executor, "_max_workers", None)
        self.window = workers if isinstance(workers, int) and workers > 0 else (os.cpu_count() or 2)
        self.lookahead: Callable[[], list[tuple[Candidate, int]]] | None = None
        """Set by the engine: the probes it will start next if the current round finds nothing."""
        self.prefetch = Prefetch()
        self._ahead: list[tuple[Candidate, int]] | None = None

    # -- one round ----------------------------------------------------------------------------------------

    def first_reproducing(self, trials: Sequence[Trial], *, quiet: bool = False) -> tuple[int, Decision] | None:
        """Index and verdict of the first trial that reproduces f, or None if none does.

        `quiet` (the verification pass) does not count or log verdicts already known.
        Raises BudgetExhausted when a budget runs out before the answer is known.
        """
        if self.executor is None:
            return self._serial(trials, quiet)
        return self._concurrent(trials, quiet)

    def _serial(self, trials: Sequence[Trial], quiet: bool) -> tuple[int, Decision] | None:
        for index, trial in enumerate(trials):
            status = self._status(trial)
            if isinstance(status, str):
                self._consult_skip(trial, status, quiet)
                continue
            if isinstance(status, Decision):
                self._consult(trial, status, cached=True, quiet=quiet)
                decision = status
            else:
                decision = self._decide_serially(status)
                self._consult(trial, decision, cached=False, quiet=quiet)
            if decision.reproduces:
                return index, decision
        return None

    def _decide_serially(self, state: _Open) -> Decision:
        while (verdict := self.policy.verdict(state.outcomes)) is None:
            reason = self.budget.exhausted(self.counters.started)
            if reason is not None:
                raise BudgetExhausted(reason)
            self.counters.started += 1
            attempt = len(state.outcomes)
            try:
                result = call_probe(self.probe, state.trial.candidate, attempt, self.counters)
            except ProbeCancelled as cancelled:
                raise self.budget.stop(cancelled.reason) from None
            self._take(state, attempt, checked_observation(result))
        return self._decide(state, verdict)

    def _concurrent(self, trials: Sequence[Trial], quiet: bool) -> tuple[int, Decision] | None:
        assert self.executor is not None
        self.counters.started -= self.prefetch.cancel_except({frozenset(trial.candidate) for trial in trials})
        self._ahead = None
        statuses: list[str | Decision | _Open] = [self._status(trial) for trial in trials]
        for status in statuses:
            if isinstance(status, _Open) and (verdict := self.policy.verdict(status.outcomes)) is not None:
                self._decide(status, verdict)
        futures: dict[concurrent.futures.Future[Any], tuple[_Open, int]] = {}
        position = {id(status): index for index, status in enumerate(statuses)}
        finished = False
        try:
            while not (resolution := self._resolve(statuses))[0]:
                reason = self._submit(statuses, futures)
                if not futures:
                    raise BudgetExhausted(reason or "budget: max_probes")
                done, _ = concurrent.futures.wait(
                    futures, timeout=self.budget.seconds_left(), return_when=concurrent.futures.FIRST_COMPLETED
                )
                if not done:  # the time budget ran out while probes run: they are abandoned (see close())
                    raise self.budget.stop("budget: max_seconds")
                for future in sorted(done, key=lambda f: position[id(futures[f][0])]):
                    state, attempt = futures.pop(future)
                    self._finish(state, attempt, future)
            finished = True
        finally:
            for future in list(futures):
                if future.cancel():  # queued, never started: not a simulation
                    futures.pop(future)
                    self.counters.started -= 1
            if finished:  # results that are already there are recorded; the running ones are kept for later
                for future in [f for f in futures if f.done()]:
                    state, attempt = futures.pop(future)
                    self._finish(state, attempt, future)
            for future, (state, attempt) in futures.items():
                self.prefetch.adopt(state.trial.candidate, attempt, future)
            self._keep_undecided(statuses)
        answer = resolution[1]
        last = len(statuses) - 1 if answer is None else answer
        for trial, status in zip(trials[: last + 1], statuses[: last + 1], strict=True):
            if isinstance(status, str):
                self._consult_skip(trial, status, quiet)
            elif isinstance(status, Decision):
                self._consult(trial, status, cached=True, quiet=quiet)
            else:
                assert status.decision is not None
                self._consult(trial, status.decision, cached=False, quiet=quiet)
        if answer is None:
            return None
        chosen = statuses[answer]
        decision = chosen if isinstance(chosen, Decision) else chosen.decision  # type: ignore[union-attr]
        assert isinstance(decision, Decision)
        return answer, decision

    def _submit(
        self,
        statuses: list[str | Decision | _Open],
        futures: dict[concurrent.futures.Future[Any], tuple[_Open, int]],
    ) -> str | None:
        """Start attempts of undecided candidates, earliest first, up to the window and budget.

        Only candidates before the first one known to reproduce f can still change the answer. First one
        attempt for each of them with none running; then, while workers are still idle, the later re-runs
        the fixed deflake policy may need (speculatively: results are applied in attempt order and those
        past the verdict are dropped, so the decisions are exactly the serial ones); then, if workers are
        still idle, the engine's next probes (prefetched, see prefetch.py).
        """
        assert self.executor is not None
        undecided = self._undecided(statuses)
        idle = [state for state in undecided if not state.in_flight and not state.early]
        first = [(state, state.next_attempt()) for state in idle]
        limit = runs_worth_starting_ahead(self.policy)
        speculative = [
            (state, attempt)
            for state in undecided
            for attempt in range(state.next_attempt() + any(state is other for other in idle), limit)
        ]
        for state, attempt in first + speculative:
            if len(futures) >= self.window:
                return None
            if attempt in state.in_flight:
                continue
            future = self.prefetch.take(state.trial.candidate, attempt)
            if future is None:
                reason = self.budget.exhausted(self.counters.started)
                if reason is not None:
                    return reason
                self.counters.started += 1
                future = self.executor.submit(call_probe, self.probe, state.trial.candidate, attempt, self.counters)
            state.in_flight.add(attempt)
            futures[future] = (state, attempt)
        self._prefetch_ahead(statuses, busy=len(futures))
        return None

    @staticmethod
    def _undecided(statuses: Sequence[str | Decision | _Open]) -> list[_Open]:
        """Open, undecided candidates before the first one known to reproduce f."""
        undecided: list[_Open] = []
        for status in statuses:
            decision = status if isinstance(status, Decision) else getattr(status, "decision", None)
            if decision is not None and decision.reproduces:
                break
            if isinstance(status, _Open) and status.decision is None:
                undecided.append(status)
        return undecided

    def _prefetch_ahead(self, statuses: Sequence[str | Decision | _Open], busy: int) -> None:
        """Start the engine's next probes on the workers this round leaves idle (never past the budget)."""
        if self.lookahead is None or busy + self.prefetch.running() >= self.window:
            return
        if self._ahead is None:
            self._ahead = self.lookahead()
        assert self.executor is not None
        executor, probe = self.executor, self.probe
        in_round = {frozenset(status.trial.candidate) for status in statuses if isinstance(status, _Open)}
        for candidate, attempt in self._ahead:
            key = (frozenset(candidate), attempt)
            if key in self.prefetch or key[0] in in_round:
                continue
            if busy + self.prefetch.running() >= self.window or self.budget.exhausted(self.counters.started):
                return
            self.counters.started += 1
            self.prefetch.start(
                key, functools.partial(executor.submit, call_probe, probe, candidate, attempt, self.counters)
            )

    def planned(self, trials: Sequence[Trial]) -> list[tuple[Candidate, int]]:
        """The probes deciding `trials` would start first: a first attempt of each undecided candidate, then
        the re-runs a fixed-length deflake rule may need."""
        opened = [status for status in map(self._status, trials) if isinstance(status, _Open)]
        opened = [state for state in opened if self.policy.verdict(state.outcomes) is None]
        limit = runs_worth_starting_ahead(self.policy)
        first = [(state.trial.candidate, len(state.outcomes)) for state in opened]
        later = [(s.trial.candidate, a) for s in opened for a in range(len(s.outcomes) + 1, limit)]
        return first + later

    def close(self) -> None:
        """Forget the prefetched probes: cancel those not started, count the others as abandoned."""
        self.counters.abandoned += self.prefetch.close()

    def _finish(self, state: _Open, attempt: int, future: concurrent.futures.Future[Any]) -> None:
        state.in_flight.discard(attempt)
        try:
            result = future.result()
        except ProbeCancelled as cancelled:
            raise self.budget.stop(cancelled.reason) from None
        state.early[attempt] = checked_observation(result)
        while state.decision is None and len(state.outcomes) in state.early:
            current = len(state.outcomes)
            self._take(state, current, state.early.pop(current))
            if (verdict := self.policy.verdict(state.outcomes)) is not None:
                self._decide(state, verdict)
        if state.decision is not None:  # speculative re-runs past the verdict: kept for the failure-rate runs
            for later, observation in state.early.items():
                self.prefetch.keep(state.trial.candidate, later, observation)
            state.early.clear()

    def _keep_undecided(self, statuses: Sequence[str | Decision | _Open]) -> None:
        """Candidates the round left undecided keep their runs (outcomes, trace, early results), so a later
        round that needs one again (after a back-off, say) goes on from them instead of simulating again."""
        for status in statuses:
            if isinstance(status, _Open) and status.decision is None and (status.outcomes or status.early):
                self._left_open[frozenset(status.trial.candidate)] = status

    @staticmethod
    def _resolve(statuses: Sequence[str | Decision | _Open]) -> tuple[bool, int | None]:
        """(known, index): is the round's answer known yet, and the first reproducing index (or None)."""
        for index, status in enumerate(statuses):
            if isinstance(status, str):
                continue
            decision = status if isinstance(status, Decision) else status.decision
            if decision is None:
                return False, None
            if decision.reproduces:
                return True, index
        return True, None

    # -- extra runs of a decided world ----------------------------------------------------------------------

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
        fails = done = 0
        exhausted: str | None = None
        submitted: list[tuple[int, concurrent.futures.Future[Any]]] = []
        for attempt in attempts:
            if attempt in known:
                continue
            future = self.prefetch.take(candidate, attempt) if self.executor is not None else None
            if future is None:
                exhausted = self.budget.exhausted(self.counters.started)
                if exhausted is not None:
                    break
                self.counters.started += 1
                if self.executor is not None:
                    future = self.executor.submit(call_probe, self.probe, candidate, attempt, self.counters)
                else:
                    future = concurrent.futures.Future()
                    try:
                        future.set_result(call_probe(self.probe, candidate, attempt, self.counters))
                    except ProbeCancelled as cancelled:
                        exhausted = self.budget.stop(cancelled.reason).reason
                        break
            submitted.append((attempt, future))
        results: dict[int, Observation] = {}
        stopped = exhausted is not None and exhausted != "budget: max_probes"  # time is up: wait for nothing more
        try:
            for attempt, future in submitted:
                if stopped and future.cancel():
                    self.counters.started -= 1
                    continue
                try:
                    results[attempt] = checked_observation(future.result(timeout=self.budget.seconds_left()))
                except ProbeCancelled as cancelled:
                    exhausted, stopped = self.budget.stop(cancelled.reason).reason, True
                except concurrent.futures.TimeoutError:
                    exhausted, stopped = self.budget.stop("budget: max_seconds").reason, True
                    self.prefetch.adopt(candidate, attempt, future)  # abandoned (see close())
        finally:
            for attempt, future in submitted:
                if attempt not in results and not future.done() and future.cancel():
                    self.counters.started -= 1
        for attempt in attempts:
            if attempt in known:
                outcome = known[attempt]
            elif attempt in results:
                observation = results[attempt]
                self._log_probe(Trial(candidate, purpose), attempt, observation, purpose=purpose)
                if purpose == "calibration":
                    self.counters.probes += 1
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

    # -- bookkeeping --------------------------------------------------------------------------------------

    def _status(self, trial: Trial) -> str | Decision | _Open:
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
            return _Open(trial, list(earlier.outcomes), earlier.trace, early=early)
        return _Open(trial, list(self.preloaded.get(key, ())))

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

    def _take(self, state: _Open, attempt: int, observation: Observation) -> None:
        self.counters.probes += 1
        state.outcomes.append(observation.outcome)
        if observation.outcome is Outcome.FAIL and state.trace is None:
            state.trace = observation.trace
        self._log_probe(state.trial, attempt, observation, purpose="reduce")
        self.on_probe(state.trial.candidate, observation.outcome)

    def _log_probe(self, trial: Trial, attempt: int, observation: Observation, *, purpose: str) -> None:
        if observation.outcome is Outcome.ERROR:
            self.counters.errors += 1
        self._write(
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

    def _decide(self, state: _Open, verdict: bool) -> Decision:
        fails = sum(1 for outcome in state.outcomes if outcome is Outcome.FAIL)
        errors = sum(1 for outcome in state.outcomes if outcome is Outcome.ERROR)
        valid = [outcome for outcome in state.outcomes if outcome is not Outcome.ERROR]
        errored = not verdict and errors > 0 and self.policy.verdict(valid) is not False
        decision = Decision(reproduces=verdict, fails=fails, runs=len(state.outcomes), trace=state.trace,
                            errored=errored)
        state.decision = decision
        key = frozenset(state.trial.candidate)
        if errored:  # not a verdict: "not f" for this reduction only, tried again on resume
            self.errored[key] = decision
            self._errored_runs[key] = list(state.outcomes)
            self.counters.errored.add(key)
        else:
            self.cache[key] = decision
        record: dict[str, Any] = {
            "event": "errored" if errored else "accept" if verdict else "reject",
            "kind": state.trial.kind,
            "candidate": list(state.trial.candidate),
            "size": len(state.trial.candidate),
            "reproduces": verdict,
            "fails": fails,
            "runs": len(state.outcomes),
        }
        if errors:
            record["errors"] = errors
        self._write(record)
        return decision

    def _consult(self, trial: Trial, decision: Decision, *, cached: bool, quiet: bool) -> None:
        """The serial algorithm looks at this verdict now: feed the learner, count and log cache hits."""
        key = frozenset(trial.candidate)
        if key not in self._consulted:
            self._consulted.add(key)
            self.context.history.append(Verdict(frozenset(key - self.keep), decision.reproduces))
        if cached and not quiet:
            self.counters.cache_hits += 1
            record: dict[str, Any] = {
                "event": "cache-hit",
                "kind": trial.kind,
                "candidate": list(trial.candidate),
                "size": len(trial.candidate),
                "reproduces": decision.reproduces,
                "fails": decision.fails,
                "runs": decision.runs,
            }
            if decision.errored:
                record["errored"] = True
            self._write(record)

    def _consult_skip(self, trial: Trial, reason: str, quiet: bool) -> None:
        key = frozenset(trial.candidate)
        first_time = key not in self.counters.skipped
        self.counters.skipped.add(key)
        if first_time or not quiet:
            self._write(
                {
                    "event": "skip",
                    "kind": trial.kind,
                    "candidate": list(trial.candidate),
                    "size": len(trial.candidate),
                    "reason": reason,
                }
            )

    def _write(self, record: dict[str, Any]) -> None:
        if self.log is not None:
            record["elapsed"] = round(self.elapsed(), 6)
            self.log.write(record)
