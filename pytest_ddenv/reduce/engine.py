"""`reduce`: Algorithm 1 of the paper made ddmin-faithful, ending with a proof of 1-minimality.

Each round partitions the current world (partition schema), orders the parts (priority schema), and tries
the parts ("subsets") in priority order, then their complements (by default in reverse priority order:
the part least likely to matter is removed first; a candidate inside one already rejected goes to the end of
the round: a monotone failure cannot reproduce it). The first candidate that reproduces f (after
deflaking) becomes the current world. Granularity follows ddmin (after a subset: n_partitions; after a
complement of k parts: max(n-k, 2), k > 1 for a grown removal; no progress: min(2n, size)) or the paper (n+1
every round). When no candidate of the finest round (every part one element) reproduces f, a verification
pass tries removing each single remaining element; only if none reproduces f is the result declared
1-minimal. Finally the minimal world's failure rate is compared with the original's on fresh runs
(rate_check.py); when it is significantly lower, the reduction backs off to the last accepted world whose
rate holds, rejects every accepted world after it, and reduces again from there (at most
`backoff.MAX_BACKOFFS` times). See docs/algorithm.md.

What a round tries is `rounds.py`'s, the chain of accepted worlds and the back-off search `backoff.py`'s,
the result and the start and end records `result.py`'s; the engine keeps the state and calls them in order.
"""

from __future__ import annotations

import concurrent.futures
import os
import time
from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import replace
from typing import Any

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.backoff import AcceptedChain, Step
from pytest_ddenv.reduce.budget import Budget, BudgetExhausted
from pytest_ddenv.reduce.calibration import calibrate
from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.deflake import CalibratedReruns
from pytest_ddenv.reduce.independence import WORLD_INDEPENDENT, reproduces_without_elements
from pytest_ddenv.reduce.keywords import keyword_settings
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.prober import probing
from pytest_ddenv.reduce.rate_check import Drift, RateChecker
from pytest_ddenv.reduce.rates import RateComparison
from pytest_ddenv.reduce.refusals import precondition_kept, rate_without_kept
from pytest_ddenv.reduce.result import build_reduction, end_event, notes_of, plural, start_event
from pytest_ddenv.reduce.resume import open_log, resume
from pytest_ddenv.reduce.rounds import Part, Plan, fresh_plan, grown_removal, next_granularity, trials_of
from pytest_ddenv.reduce.settings import ReductionSettings, Settings, validate
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import (
    Candidate,
    Decision,
    FirstCutResult,
    Geometry,
    Outcome,
    Probe,
    ProgressEvent,
    Reduction,
    ReductionInterrupted,
    Trace,
)


@keyword_settings
def reduce(
    elements: Sequence[str],
    probe: Probe,
    settings: ReductionSettings | None = None,
    *,
    geometry: Geometry | None = None,
    reference: Trace | None = None,
    log: ProbeLog | str | os.PathLike[str] | None = None,
    executor: concurrent.futures.Executor | None = None,
    on_progress: Callable[[ProgressEvent], None] | None = None,
) -> Reduction:
    """Reduce a failing world to a 1-minimal failing sub-world.

    `elements` are the names of the world's elements (original order; the original world is assumed to
    fail with f: its run is `reference`, attempt 0). `probe(candidate, attempt)` simulates a sub-world
    (names in original order, `keep` elements included) and returns a ProbeObservation. `settings`: how to
    reduce (`ReductionSettings`, every field documented in docs/algorithm.md; default: the defaults).
    `geometry` and `reference` are what the partition and priority schemas read; `log` the run log (a path
    or a `ProbeLog`: verdicts are resumed from it); `executor` runs a round's probes concurrently
    (`settings.workers` of them at once); `on_progress` is called with a `ProgressEvent` after each step.
    Raises ReductionError for invalid arguments and ReductionInterrupted (carrying the partial `.reduction`)
    on KeyboardInterrupt; budgets end the reduction early with the best world so far and
    ``incomplete_reason`` set.
    """
    checked = validate(elements, probe, ReductionSettings() if settings is None else settings, geometry=geometry,
                       reference=reference, executor=executor, log=log, on_progress=on_progress)
    return _Engine(checked).run()


class _Engine:
    """The state of one reduction."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.started_at = time.monotonic()
        self.log = open_log(settings)
        self.cache: MutableMapping[Any, Any] = settings.cache if settings.cache is not None else {}
        resumed = resume(self.log, self.cache)
        self.resumed = resumed.resumed
        self.history = resumed.history
        """Probes decided by earlier runs of a resumed log (reported as part of the whole history)."""
        self.unverified = 0
        """Single removals of the result that were rejected on ERROR runs alone (even after a retry)."""
        self.current: tuple[str, ...] = settings.reducible
        self.context = Context(
            elements=settings.reducible, geometry=settings.geometry, trace=settings.reference, seed=settings.seed
        )
        self.context.history.append(Verdict(frozenset(self.current), True))
        self.granularity = min(settings.n_partitions, len(self.current))
        self.round_index = 0
        self.carried: Plan | None = None
        """After a complement was adopted, ddmin goes on with the remaining n-1 parts."""
        self.streak = 0
        """Carried rounds in a row whose first candidate was adopted: the next one first tries removing the
        next 2**streak parts at once (`grown_removal`)."""
        self.minimal_runs = 1  # the reference run of the original world is its attempt 0
        self.probing = probing(
            probe=settings.probe, policy=settings.policy, keep=settings.keep, preconditions=settings.preconditions,
            cache=self.cache, preloaded=resumed.preloaded,
            budget=Budget(settings.max_probes, settings.max_seconds, self.started_at), executor=settings.executor,
            workers=settings.workers, log=self.log, context=self.context, elapsed=self.elapsed,
            on_probe=lambda candidate, outcome: self.emit("probe", candidate=candidate, outcome=outcome),
            lookahead=self.lookahead if settings.executor is not None else None,
        )
        self.steps: list[tuple[int, int]] = [(0, len(settings.elements))]
        self.rates = RateChecker(self.probing.extra_runs, self.log, settings.elements, settings.failure_rate_runs,
                                 self.write)
        self.rate_check: RateComparison | None = None
        self.chain = AcceptedChain(Step(settings.elements, 1, settings.reference), self.rates, self.cache)
        self.probing.scheduler.after_rejection = self.chain.watch_drift
        self.precondition_check: tuple[int, int] | None = None
        self.verifying = False
        self.calibration: tuple[int, int] | None = None
        self.independent = False
        self.first_cut: FirstCutResult | None = None
        self.cutting: Trial | None = None
        """The first cut's trial while it is decided: what idle workers run ahead (not the whole world's round)."""

    # -- driver -------------------------------------------------------------------------------------------

    def run(self) -> Reduction:
        try:
            try:
                self.write_start()
                one_minimal, incomplete = self.reduce_and_check()
                failure_rate = (0, 0) if self.independent else self.final_rate()
                if not self.independent and self.settings.precondition_check:
                    self.check_without_precondition_kept()
            except KeyboardInterrupt as interrupt:
                if isinstance(interrupt, ReductionInterrupted):
                    raise
                partial = self.result(one_minimal=False, incomplete="interrupted", failure_rate=(0, 0))
                self.write_end(partial)
                raise ReductionInterrupted(partial) from interrupt
            reduction = self.result(one_minimal=one_minimal, incomplete=incomplete, failure_rate=failure_rate)
            self.write_end(reduction)
            return reduction
        finally:
            self.probing.runner.close()
            if self.log is not None:
                self.log.close()

    def reduce_and_check(self) -> tuple[bool, str | None]:
        """Reduce to a 1-minimal world, compare its failure rate with the original's and back off while it
        is significantly lower; (1-minimal, incomplete reason)."""
        try:
            if self.settings.check_independence:
                self.independent = reproduces_without_elements(
                    self.settings.preconditions, self.current, self.settings.keep, self.full, log=self.log,
                    extra_runs=self.probing.extra_runs)
                if self.independent:
                    return False, WORLD_INDEPENDENT
            self.calibrate()
            self.try_first_cut()
            while True:
                try:
                    one_minimal = self.reduce_to_one_minimal()
                except Drift as drift:  # caught during the reduction: back off from there
                    self.rate_check = drift.comparison
                    self.chain.drift_backoffs += 1
                    if not self.back_off(during=True):
                        return False, "budget: the rate comparison was stopped"
                    continue
                if one_minimal and self.unverified:
                    return False, f"not verified: {plural(self.unverified, 'candidate')} errored"
                if len(self.chain.steps) == 1:  # nothing removed: no comparison to make
                    return one_minimal, None
                self.rate_check = self.chain.compare_last()
                if self.rate_check is None or self.rate_check.decision != "below" or \
                        not self.chain.may_back_off_at_end():
                    return one_minimal, None
                if not self.back_off():
                    return one_minimal, None
        except BudgetExhausted as exhausted:
            return False, exhausted.reason

    def back_off(self, *, during: bool = False) -> bool:
        """The minimal world fails significantly less often than the original: find the last accepted world
        whose rate holds (`AcceptedChain.back_off`), reject every later one ("rate-below") and go on reducing
        from it. `during` (the drift watch caught the last accepted world): reject it alone and go on from the
        world before it, unsearched (the watch and the end of the run still compare it). False when the budget
        stopped the search."""
        below = self.rate_check
        assert below is not None
        back = self.chain.back_off(below, during=during, context=self.context, keep=self.settings.keep,
                                   write=self.write)
        if back is None:
            return False
        self.rate_check = None
        self.current = tuple(name for name in back.world if name not in self.settings.keep)
        if back.trace is not None:  # none from a log written before traces were logged: keep the one the schemas read
            self.context.trace = back.trace
        self.minimal_runs = back.fresh_from
        self.granularity = min(self.settings.n_partitions, len(self.current))
        self.carried = None
        self.streak = 0
        self.unverified = 0
        self.steps.append((self.probes(), len(back.world)))
        self.write(events.BackOff(candidate=back.world, size=len(back.world), probes=self.probes()))
        self.emit("step", candidate=back.world)
        return True

    def calibrate(self) -> None:
        """deflake="auto": measure the original world's failure rate (or read it from a resumed log) and
        size the deflake rule from it. Attempt 0 is the reference failure; these are attempts 1, 2, ..."""
        policy = self.settings.policy
        if not isinstance(policy, CalibratedReruns) or not self.current:
            return
        self.calibration, rule = calibrate(policy, self.settings.elements, log=self.log, rates=self.rates,
                                           extra_runs=self.probing.extra_runs, write=self.write)
        self.probing.decider.policy = rule
        self.minimal_runs = 1 + self.calibration[1]  # an unreduced world's failure-rate runs continue after these

    def try_first_cut(self) -> None:
        """The caller's first cut (`first_cut`: the driver's cut by reach), tried as one trial judged like any
        other (deflake rule, log, cache: a resumed log answers without a simulation) before the rounds; adopted
        as a step when it reproduces f. Its simulations count as any other's."""
        if self.settings.first_cut is None:
            return
        whole = self.full(self.current)
        trial = Trial(self.full(tuple(name for name in self.current if name in self.settings.first_cut)), "reach")
        if len(trial.candidate) == len(whole):
            return
        before = self.probing.counters.simulations
        self.cutting = trial
        try:
            found = self.probing.scheduler.first_reproducing([trial])
        finally:
            self.cutting = None
        self.first_cut = FirstCutResult(len(whole), len(trial.candidate), found is not None,
                                        self.probing.counters.simulations - before)
        self.write(events.FirstCut(original=len(whole), kept=len(trial.candidate),
                                   decision="holds" if found is not None else "does-not-hold",
                                   simulations=self.first_cut.simulations))
        if found is not None:
            self.adopt(trial, found[1])
            self.granularity = min(self.settings.n_partitions, len(self.current))

    def reduce_to_one_minimal(self) -> bool:
        """ddmin rounds until the finest round fails, then the verification pass; True when 1-minimal."""
        while self.current:
            self.granularity = max(1, min(self.granularity, len(self.current)))
            found = self.play_round()
            if found is not None:
                continue
            if self.granularity < len(self.current):
                self.granularity = self.coarser_or_finer(progress=None)
                continue
            if not self.verify():
                return True
        return True

    def play_round(self) -> Trial | None:
        """One round at the current granularity; adopts and returns the accepted trial, if any."""
        carried = self.carried if self.carried is not None and len(self.carried.ordered) == self.granularity else None
        self.carried = None
        plan = carried if carried is not None else self.fresh_plan(self.granularity)
        trials = self.trials_of(plan)
        grown = grown_removal(plan, self.streak, self.settings.granularity, self.current, self.full) \
            if carried is not None else None
        if grown is not None:
            trials.insert(0, grown)
        self.write(events.Round(index=self.round_index, granularity=self.granularity, size=len(self.full(self.current)),
                                parts=tuple(tuple(part) for part in plan.ordered),
                                removal_order=tuple(plan.ordered.index(part) for part in plan.removal),
                                subsets=plan.subsets))
        self.emit("round")
        self.round_index += 1
        found = self.probing.scheduler.first_reproducing([trial for trial, _ in trials])
        self.streak = self.streak + 1 if found is not None and found[0] == 0 and carried is not None else 0
        if found is None:
            return None
        trial, parts = trials[found[0]]
        self.adopt(trial, found[1])
        self.granularity = self.coarser_or_finer(progress=trial.kind, removed=len(parts))
        if trial.kind == "complement" and self.settings.granularity == "ddmin":
            self.carried = plan.without(parts)
        return trial

    def fresh_plan(self, granularity: int) -> Plan:
        return fresh_plan(self.settings, self.current, granularity, self.context, self.round_index)

    def verify(self) -> bool:
        """Try removing each single remaining element; adopt and return True if one still reproduces f.

        A removal rejected on ERROR runs alone is tried once more (its ERROR attempts run again); if it
        still errors, `unverified` counts it and the result is not reported 1-minimal."""
        self.emit("verify")
        trials = self.verify_trials()
        self.verifying = True
        try:
            found = self.probing.scheduler.first_reproducing(trials, quiet=True)
            while found is None and self.probing.decider.retry_errored(trials):
                found = self.probing.scheduler.first_reproducing(trials, quiet=True)
        finally:
            self.verifying = False
        if found is None:
            self.unverified = len(self.probing.decider.errored_among(trials))
            return False
        self.adopt(trials[found[0]], found[1])
        self.granularity = len(self.current)
        return True

    def verify_trials(self) -> list[Trial]:
        return [
            Trial(self.full(tuple(name for name in self.current if name != removed)), "verify")
            for removed in self.current
        ]

    def lookahead(self) -> list[tuple[Candidate, int]]:
        """The probes the engine starts next if the current round (or verification pass) finds nothing:
        prefetched on idle workers (see prefetch.py). A guess: a schema error here is left to the real round."""
        if self.cutting is not None:
            return self.probing.scheduler.planned([self.cutting])
        if self.verifying or not self.current:
            runs = self.rates.looks[0] if self.rates.looks else 0
            return [(self.full(self.current), attempt)
                    for attempt in range(self.minimal_runs, self.minimal_runs + runs)]
        if self.granularity >= len(self.current):
            return self.probing.scheduler.planned(self.verify_trials())
        try:
            plan = self.fresh_plan(self.coarser_or_finer(progress=None))
        except Exception:  # noqa: BLE001 - only a guess; the real round reports the error
            return []
        trials = self.trials_of(plan)
        return self.probing.scheduler.planned([trial for trial, _ in trials])

    def coarser_or_finer(self, progress: str | None, removed: int = 1) -> int:
        """The next granularity after a round that adopted a subset, a complement (of `removed` parts), or
        nothing (None)."""
        return next_granularity(self.settings, self.granularity, len(self.current), progress, removed)

    def trials_of(self, plan: Plan) -> list[tuple[Trial, tuple[Part, ...]]]:
        return trials_of(plan, self.current, self.full, keep=self.settings.keep, below=self.rates.below_worlds(),
                         context=self.context)

    def adopt(self, trial: Trial, decision: Decision) -> None:
        self.unverified = 0
        self.current = tuple(name for name in trial.candidate if name not in self.settings.keep)
        if decision.trace is not None:
            self.context.trace = decision.trace
        self.minimal_runs = decision.runs
        self.chain.steps.append(Step(trial.candidate, decision.runs, decision.trace))
        self.steps.append((self.probes(), len(trial.candidate)))
        self.write(events.Step(kind=trial.kind, candidate=tuple(trial.candidate), size=len(trial.candidate),
                               probes=self.probes()))
        self.emit("step", candidate=trial.candidate)

    def final_rate(self) -> tuple[int, int]:
        """(fails, runs) of the minimal world's fresh runs: those of the rate comparison, or (nothing was
        removed, or the comparison is off) the original world's first look."""
        rate = self.chain.minimal_rate(self.rate_check)
        if rate is None:
            return (0, 0)
        minimal = self.full(self.current)
        self.write(events.FailureRate(candidate=minimal, fails=rate.fails, runs=rate.runs))
        return rate.fails, rate.runs

    def check_without_precondition_kept(self) -> None:
        """Cheap information: does the minimal world without its precondition-kept elements still fail?
        A few runs (the first look), preconditions bypassed, within the budget."""
        checked = rate_without_kept(self.settings.preconditions, self.current, self.full, self.rates,
                                    self.probing.runner.exhausted)
        if checked is not None:
            world, rate = checked
            self.precondition_check = (rate.fails, rate.runs)
            self.write(events.PreconditionCheck(candidate=world, fails=rate.fails, runs=rate.runs))

    # -- helpers ------------------------------------------------------------------------------------------

    def full(self, reducible: Sequence[str]) -> Candidate:
        chosen = set(reducible) | self.settings.keep
        return tuple(name for name in self.settings.elements if name in chosen)

    def elapsed(self) -> float:
        return time.monotonic() - self.started_at

    def probes(self) -> int:
        """Probes decided in the whole history: the resumed log's and this call's."""
        return self.history + self.probing.counters.probes

    def emit(self, kind: str, *, candidate: Candidate | None = None, outcome: Outcome | None = None) -> None:
        if self.settings.on_progress is None:
            return
        self.settings.on_progress(ProgressEvent(
            kind=kind, size=len(self.full(self.current)), probes=self.probes(), granularity=self.granularity,
            elapsed=self.elapsed(), candidate=candidate, outcome=outcome))

    def write(self, event: events.Event) -> None:
        if self.log is not None:
            self.log.write(replace(event, elapsed=round(self.elapsed(), 6)))

    def result(self, *, one_minimal: bool, incomplete: str | None, failure_rate: tuple[int, int]) -> Reduction:
        return build_reduction(
            self.settings, self.probing.counters,
            minimal=self.full(self.current), probes=self.probes(), steps=self.steps, one_minimal=one_minimal,
            incomplete=incomplete, failure_rate=failure_rate, wall_time=self.elapsed(),
            deflake=self.settings.policy.label if self.calibration is None
            else f"auto:{self.probing.decider.policy.label}",
            calibration=self.calibration, resumed_probes=self.history,
            notes=notes_of(self.log.notes if self.log is not None else [], self.chain.notes, self.unverified),
            rate_check=self.rate_check, rate_backoffs=self.chain.backoffs,
            precondition_kept=precondition_kept(self.settings.preconditions, self.current, self.full),
            without_precondition_kept=self.precondition_check, independent=self.independent,
            first_cut=self.first_cut,
        )

    def write_start(self) -> None:
        self.write(start_event(self.settings, resumed=self.resumed))
        self.emit("start")

    def write_end(self, reduction: Reduction) -> None:
        self.write(end_event(reduction))
        self.emit("end")
