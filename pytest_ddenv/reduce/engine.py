"""`reduce`: Algorithm 1 of the paper made ddmin-faithful, ending with a proof of 1-minimality.

Each round partitions the current world (partition schema), orders the parts (priority schema), and tries
the parts ("subsets") in priority order, then their complements (by default in reverse priority order:
the part least likely to matter is removed first; a candidate inside one already rejected goes to the end of
the round: a monotone failure cannot reproduce it). The first candidate that reproduces f (after
deflaking) becomes the current world. Granularity follows ddmin (after a subset: n_partitions; after a
complement: max(n-1, 2); no progress: min(2n, size)) or the paper (n+1 every round). When no candidate
of the finest round (every part one element) reproduces f, a verification pass tries removing each single
remaining element; only if none reproduces f is the result declared 1-minimal. Finally the minimal world's
failure rate is compared with the original's on fresh runs (rate_check.py); when it is significantly lower,
the reduction backs off to the last accepted world whose rate holds, rejects the step after it, and reduces
again from there (at most MAX_BACKOFFS times). See docs/algorithm.md.
"""

from __future__ import annotations

import concurrent.futures
import functools
import os
import time
from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.budget import Budget, BudgetExhausted
from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.deflake import CalibratedReruns
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.prober import probing
from pytest_ddenv.reduce.rate_check import Drift, DriftWatch, RateChecker
from pytest_ddenv.reduce.rates import RateComparison
from pytest_ddenv.reduce.settings import SETTING_NAMES, ReductionSettings, Settings, validate
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

INDEPENDENCE = "independence"
"""The log's purpose of the run of the world without its reducible elements (`check_independence`)."""
WORLD_INDEPENDENT = "world-independent"
"""The incomplete reason of a reduction that found the failure independent of the elements."""
GROWN_MIN_PARTS = 8
"""The fewest parts a carried round needs for a grown removal (`_Engine.grown_removal`)."""
MAX_BACKOFFS = 3
"""How many times a reduction backs off from a minimal world that fails significantly less often than the
original before it reports that world with its rate as it is."""


def plural(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def _keyword_settings(function: Callable[..., Reduction]) -> Callable[..., Reduction]:
    """The former spelling `reduce(elements, probe, max_probes=10, deflake=0, ...)` still works: each keyword
    that names a `ReductionSettings` field goes into the settings (not beside a `settings=` of its own)."""

    @functools.wraps(function)
    def reduce(*arguments: Any, **keywords: Any) -> Reduction:
        named = {name: keywords.pop(name) for name in SETTING_NAMES if name in keywords}
        unknown = sorted(set(keywords) - set(_ARGUMENTS))
        if unknown:
            raise ReductionError(f"reduce() got an unknown argument {unknown[0]!r}; its arguments are "
                                 f"{', '.join(_ARGUMENTS)}, and the settings are "
                                 f"ReductionSettings({', '.join(SETTING_NAMES)})")
        if named:
            given = keywords.pop("settings", None) if len(arguments) < 3 else arguments[2]
            if given is not None:
                raise ReductionError(f"reduce(): {', '.join(named)} given beside settings=; put them in the "
                                     "ReductionSettings")
            keywords["settings"] = ReductionSettings(**named)
            arguments = arguments[:2]
        return function(*arguments, **keywords)

    return reduce


@_keyword_settings
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


def _accepted_before_rate_below(log: ProbeLog) -> dict[frozenset[str], Decision]:
    """The acceptances a rate comparison undid later in `log`: a resumed reduction accepts them again and
    undoes them at the same point, from the logged runs (the drift watch's or the end's comparison), so it
    takes the same path without a new simulation."""
    accepted: dict[frozenset[str], Decision] = {}
    undone: dict[frozenset[str], Decision] = {}
    for event in log.own_events():
        key = frozenset(event.candidate) if isinstance(event, (events.Accept, events.RateBelow)) else None
        if isinstance(event, events.Accept) and key is not None:
            accepted[key] = Decision(reproduces=True, fails=event.fails, runs=event.runs, errors=event.errors or 0)
        elif isinstance(event, events.RateBelow) and key in accepted:
            undone[key] = accepted[key]
    return undone


_ARGUMENTS = ("elements", "probe", "settings", "geometry", "reference", "log", "executor", "on_progress")


Part = tuple[str, ...]


@dataclass(frozen=True)
class _Step:
    """An accepted world of the reduction (the original first), with the first attempt that was not used
    to accept it (its fresh runs start there) and the trace of the failure it was accepted on."""

    world: Candidate
    fresh_from: int
    trace: Trace | None


@dataclass(frozen=True)
class _Plan:
    """The parts of one round: `ordered` by priority (subsets), `removal` the order complements are tried."""

    ordered: list[Part]
    removal: list[Part]
    subsets: bool
    """False when every part alone is already known not to reproduce f (a carried-over round)."""

    def without(self, removed: Sequence[Part]) -> _Plan:
        """The next round after removing the parts `removed` (one, or the next few in removal order: a grown
        removal): same parts and order, continuing after the first removed one (picire's complement offset),
        subsets not tried again (they all failed in this round)."""
        at, gone = self.removal.index(removed[0]), set(removed)
        return _Plan(
            ordered=[part for part in self.ordered if part not in gone],
            removal=[part for part in self.removal[at + 1 :] + self.removal[:at] if part not in gone],
            subsets=False,
        )


class _Engine:
    """The state of one reduction."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.started_at = time.monotonic()
        self.log = self._open_log(settings)
        self.cache: MutableMapping[Any, Any] = settings.cache if settings.cache is not None else {}
        preloaded: dict[frozenset[str], list[Outcome]] = {}
        self.resumed = self.log is not None and self.log.started_with() is not None
        self.history = self.log.decided_probes() if self.log is not None else 0
        """Probes decided by earlier runs of a resumed log (reported as part of the whole history)."""
        self.unverified = 0
        """Single removals of the result that were rejected on ERROR runs alone (even after a retry)."""
        if self.log is not None:
            for key, decision in {**self.log.decisions(), **_accepted_before_rate_below(self.log)}.items():
                self.cache.setdefault(key, decision)
            preloaded = self.log.partial_runs()
        self.current: tuple[str, ...] = settings.reducible
        self.context = Context(
            elements=settings.reducible, geometry=settings.geometry, trace=settings.reference, seed=settings.seed
        )
        self.context.history.append(Verdict(frozenset(self.current), True))
        self.granularity = min(settings.n_partitions, len(self.current))
        self.round_index = 0
        self.carried: _Plan | None = None
        """After a complement was adopted, ddmin goes on with the remaining n-1 parts."""
        self.streak = 0
        """Carried rounds in a row whose first candidate was adopted: the next one first tries removing the
        next 2**streak parts at once (`grown_removal`)."""
        self.minimal_runs = 1  # the reference run of the original world is its attempt 0
        self.probing = probing(
            probe=settings.probe,
            policy=settings.policy,
            keep=settings.keep,
            preconditions=settings.preconditions,
            cache=self.cache,
            preloaded=preloaded,
            budget=Budget(settings.max_probes, settings.max_seconds, self.started_at),
            executor=settings.executor,
            workers=settings.workers,
            log=self.log,
            context=self.context,
            elapsed=self.elapsed,
            on_probe=lambda candidate, outcome: self.emit("probe", candidate=candidate, outcome=outcome),
            lookahead=self.lookahead if settings.executor is not None else None,
        )
        self.steps: list[tuple[int, int]] = [(0, len(settings.elements))]
        self.chain: list[_Step] = [_Step(settings.elements, 1, settings.reference)]
        """The accepted worlds since the original (or since the last back-off's good world), in order."""
        self.rates = RateChecker(self.probing.extra_runs, self.log, settings.elements, settings.failure_rate_runs,
                                 self.write)
        self.rate_check: RateComparison | None = None
        self.drift = DriftWatch(self.rates)
        self.probing.scheduler.after_rejection = self.watch_drift
        self.backoffs = 0
        self.drift_backoffs = 0
        """Back-offs of the drift watch (during the reduction); the end of the run has MAX_BACKOFFS of its own."""
        self.backoff_notes: list[str] = []
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
            if self.settings.check_independence and self.reproduces_without_elements():
                return False, WORLD_INDEPENDENT
            self.calibrate()
            self.try_first_cut()
            while True:
                try:
                    one_minimal = self.reduce_to_one_minimal()
                except Drift as drift:  # caught during the reduction: back off from there
                    self.rate_check = drift.comparison
                    self.drift_backoffs += 1
                    if not self.back_off(during=True):
                        return False, "budget: the rate comparison was stopped"
                    continue
                if one_minimal and self.unverified:
                    return False, f"not verified: {plural(self.unverified, 'candidate')} errored"
                if len(self.chain) == 1:  # nothing removed: no comparison to make
                    return one_minimal, None
                self.rate_check = self.rates.compare(self.chain[-1].world, self.chain[-1].fresh_from)
                if self.rate_check is None or self.rate_check.decision != "below" or \
                        self.backoffs - self.drift_backoffs >= MAX_BACKOFFS:
                    return one_minimal, None
                if not self.back_off():
                    return one_minimal, None
        except BudgetExhausted as exhausted:
            return False, exhausted.reason

    def watch_drift(self) -> None:
        """A round's first rejection: watch the current accepted world for drift (rate_check.DriftWatch)."""
        if len(self.chain) > 1 and self.drift_backoffs < MAX_BACKOFFS:
            step = self.chain[-1]
            decision = self.cache.get(frozenset(step.world))
            self.drift.check(step.world, step.fresh_from, decision if isinstance(decision, Decision) else None)

    def reproduces_without_elements(self) -> bool:
        """Whether the world without every reducible element the preconditions allow to remove reproduces f
        in one run (attempt 0, the reference's): then the failure does not depend on the elements. Logged
        with purpose "independence" (a resumed log answers without a simulation)."""
        empty = self.full(())
        needed: tuple[str, ...] = ()
        if self.refused(empty) is not None:  # only then look for the elements the preconditions need (N checks)
            whole = self.full(self.current)
            needed = tuple(name for at, name in enumerate(whole) if name not in self.settings.keep
                           and self.refused(whole[:at] + whole[at + 1:]) is not None)
            empty = self.full(needed)
        if len(needed) == len(self.current) or self.refused(empty) is not None:
            return False
        known = self.log.measured(INDEPENDENCE, empty) if self.log is not None else {}
        fails, runs = self.probing.extra_runs.measure(empty, 0, 1, purpose=INDEPENDENCE, known=known, strict=True)
        self.independent = runs == 1 and fails == 1
        return self.independent

    def refused(self, candidate: Candidate) -> str | None:
        """Why a precondition refuses `candidate` (None: none does)."""
        return next((str(reason) for check in self.probing.preconditions if (reason := check(candidate)) is not None),
                    None)

    def back_off(self, *, during: bool = False) -> bool:
        """The minimal world fails significantly less often than the original: find the last accepted world
        whose rate holds (back from the end, 1, 2, 4 ... worlds, then a binary search), reject every later one
        ("rate-below") and go on reducing from it. `during` (the drift watch caught the last accepted world):
        reject it alone and go on from the world before it, unsearched (the watch and the end of the run still
        compare it). False when the budget stopped the search."""
        below = self.rate_check
        assert below is not None
        good, bad = (len(self.chain) - 2 if during else 0), len(self.chain) - 1
        end, distance = bad, 1
        while bad - good > 1:
            if distance and end - distance > good:  # first back from the end, 1, 2, 4 ... worlds: drift comes late
                middle, distance = end - distance, 2 * distance
            else:  # then a binary search between the last world that holds and the first below
                middle, distance = (good + bad) // 2, 0
            comparison = self.rates.compare(self.chain[middle].world, self.chain[middle].fresh_from)
            if comparison is None or comparison.decision == "continue":
                return False
            if comparison.decision == "holds":
                good, distance = middle, 0
            else:
                bad = middle
        rejected = self.chain[good + 1:]
        for step in rejected:
            outcomes = self.rates.record_of(step.world).values()
            fails = sum(outcome is Outcome.FAIL for outcome in outcomes)
            runs = sum(outcome is not Outcome.ERROR for outcome in outcomes)
            self.cache[frozenset(step.world)] = Decision(reproduces=False, fails=fails, runs=runs)
            self.context.history.append(Verdict(frozenset(step.world) - self.settings.keep, False))
            self.write(events.RateBelow(candidate=step.world, reproduces=False, fails=fails, runs=runs))
        self.backoffs += 1
        self.rate_check = None
        back = self.chain[good]
        del self.chain[good + 1:]
        self.current = tuple(name for name in back.world if name not in self.settings.keep)
        if back.trace is not None:  # a world accepted from a resumed log has none: keep the one the schemas read
            self.context.trace = back.trace
        self.minimal_runs = back.fresh_from
        self.granularity = min(self.settings.n_partitions, len(self.current))
        self.carried = None
        self.streak = 0
        self.unverified = 0
        self.steps.append((self.probes(), len(back.world)))
        self.write(events.BackOff(candidate=back.world, size=len(back.world), probes=self.probes()))
        self.backoff_notes.append(
            f"back-off {self.backoffs}: a {len(rejected[-1].world)}-element "
            f"{'accepted world (drift watch, during the reduction)' if during else 'minimal world'} failed "
            f"{'' if below.search else 'significantly '}less often than the original ({below.describe()}); "
            f"{plural(len(rejected), 'accepted world')} rejected for it, reduction resumed from "
            f"{len(back.world)} elements")
        self.emit("step", candidate=back.world)
        return True

    def calibrate(self) -> None:
        """deflake="auto": measure the original world's failure rate (or read it from a resumed log) and
        size the deflake rule from it. Attempt 0 is the reference failure; these are attempts 1, 2, ..."""
        policy = self.settings.policy
        if not isinstance(policy, CalibratedReruns) or not self.current:
            return
        known = self.log.calibration() if self.log is not None else None
        if known is None:
            original = self.settings.elements
            logged = self.log.measured("calibration", original) if self.log is not None else {}
            into = self.rates.record_of(original)
            measure = self.probing.extra_runs.measure
            fails, runs = measure(original, 1, policy.sure_runs, purpose="calibration", known=logged, strict=True,
                                  into=into)
            if fails < runs:
                more = measure(original, 1 + runs, policy.runs - runs, purpose="calibration", known=logged,
                               strict=True, into=into)
                fails, runs = fails + more[0], runs + more[1]
            rule = policy.rule_for(fails, runs)
            self.write(events.Calibration(fails=fails, runs=runs, rule=rule.label))
        else:
            fails, runs = known
            rule = policy.rule_for(fails, runs)
        self.calibration = (fails, runs)
        self.probing.decider.policy = rule
        self.minimal_runs = 1 + runs  # the failure-rate runs of an unreduced world continue after these

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
        grown = self.grown_removal(plan) if carried is not None else None
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

    def grown_removal(self, plan: _Plan) -> tuple[Trial, tuple[Part, ...]] | None:
        """After `streak` carried rounds in a row adopted their first candidate (the parts being removed one by
        one do not matter), the next 2**streak parts in removal order removed at once, tried before the
        round's own candidates (ddmin's one part a round costs a probe per part; this, about log2 of them).
        Never more than half of the other parts, and only from GROWN_MIN_PARTS parts on: a wrong guess costs
        a rejection (with `deflake=N`, N + 1 runs), more than ddmin's one part a probe saves in a small round.
        None before a streak and with the paper's granularity."""
        if self.streak == 0 or self.settings.granularity != "ddmin" or len(plan.removal) < GROWN_MIN_PARTS:
            return None
        count = min(2**self.streak, (len(plan.removal) - 1) // 2)
        if count < 2:
            return None
        parts = tuple(plan.removal[:count])
        removed = {name for part in parts for name in part}
        return Trial(self.full(tuple(name for name in self.current if name not in removed)), "complement"), parts

    def fresh_plan(self, granularity: int) -> _Plan:
        """The parts of a new round of the current world (partition schema), in priority order."""
        parts = self.settings.partitioner(self.current, granularity, self.context)
        self.check_parts(parts)
        ordered = list(self.settings.prioritizer(parts, self.context, self.round_index))
        removal = ordered[::-1] if self.settings.complement_order == "reverse" else ordered
        return _Plan(ordered=ordered, removal=removal, subsets=True)

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
        n, size = self.granularity, len(self.current)
        if self.settings.granularity == "paper":
            return max(1, min(n + 1, size))
        if progress == "subset":
            return max(1, min(self.settings.n_partitions, size))
        if progress == "complement":
            return max(1, min(max(n - removed, 2), size))
        return max(1, min(2 * n, size))

    def trials_of(self, plan: _Plan) -> list[tuple[Trial, tuple[Part, ...]]]:
        """Subsets in priority order, then complements in removal order, without repeats or no-ops."""
        current = set(self.current)
        seen = {frozenset(self.current)}
        trials: list[tuple[Trial, tuple[Part, ...]]] = []
        for kind, parts in (("subset", plan.ordered if plan.subsets else []), ("complement", plan.removal)):
            for part in parts:
                members = frozenset(part) if kind == "subset" else frozenset(current - set(part))
                if members in seen:
                    continue
                seen.add(members)
                trials.append((Trial(self.full(tuple(members)), kind), (part,)))
        below = self.rates.below_worlds()
        rejected = [verdict.members for verdict in self.context.history if not (verdict.reproduces or verdict.errored)]
        if below or rejected:  # likely not to reproduce f: tried last (reordered, never skipped)
            trials.sort(key=lambda entry: self.dominated(frozenset(entry[0].candidate), below, rejected))
        return trials

    def dominated(self, candidate: frozenset[str], below: Sequence[frozenset[str]],
                  rejected: Sequence[frozenset[str]]) -> tuple[bool, bool]:
        """(inside a world that failed significantly less often: likely the same drift; inside a candidate
        that did not reproduce f: a monotone failure would not either), the sort key of `trials_of`."""
        members = candidate - self.settings.keep
        return (any(candidate <= world for world in below), any(members <= world for world in rejected))

    def adopt(self, trial: Trial, decision: Decision) -> None:
        self.unverified = 0
        self.current = tuple(name for name in trial.candidate if name not in self.settings.keep)
        if decision.trace is not None:
            self.context.trace = decision.trace
        self.minimal_runs = decision.runs
        self.chain.append(_Step(trial.candidate, decision.runs, decision.trace))
        self.steps.append((self.probes(), len(trial.candidate)))
        self.write(events.Step(kind=trial.kind, candidate=tuple(trial.candidate), size=len(trial.candidate),
                               probes=self.probes()))
        self.emit("step", candidate=trial.candidate)

    def final_rate(self) -> tuple[int, int]:
        """(fails, runs) of the minimal world's fresh runs: those of the rate comparison, or (nothing was
        removed, or the comparison is off) the original world's first look."""
        if self.rate_check is not None:
            rate = self.rate_check.reduced
        elif self.rates.looks:
            rate = self.rates.original_rate(self.rates.looks[0]) if len(self.chain) == 1 else self.rates.rate(
                self.chain[-1].world, self.chain[-1].fresh_from, self.rates.looks[0])
        else:
            return (0, 0)
        minimal = self.full(self.current)
        self.write(events.FailureRate(candidate=minimal, fails=rate.fails, runs=rate.runs))
        return rate.fails, rate.runs

    def precondition_kept(self) -> tuple[tuple[str, str], ...]:
        """(element, reason) for each element of the minimal world whose removal a precondition refused
        (it was not shown needed for the failure, only for the scenario to be valid)."""
        kept: list[tuple[str, str]] = []
        for name in self.current:
            reason = self.refused(self.full(tuple(other for other in self.current if other != name)))
            if reason is not None:
                kept.append((name, reason))
        return tuple(kept)

    def check_without_precondition_kept(self) -> None:
        """Cheap information: does the minimal world without its precondition-kept elements still fail?
        A few runs (the first look), preconditions bypassed, within the budget."""
        kept = {name for name, _ in self.precondition_kept()}
        if not kept or not self.rates.looks or self.probing.runner.exhausted():
            return
        world = self.full(tuple(name for name in self.current if name not in kept))
        rate = self.rates.rate(world, 0, min(3, self.rates.looks[0]))
        self.precondition_check = (rate.fails, rate.runs)
        self.write(events.PreconditionCheck(candidate=world, fails=rate.fails, runs=rate.runs))

    # -- helpers ------------------------------------------------------------------------------------------

    def full(self, reducible: Sequence[str]) -> Candidate:
        chosen = set(reducible) | self.settings.keep
        return tuple(name for name in self.settings.elements if name in chosen)

    def check_parts(self, parts: Sequence[Sequence[str]]) -> None:
        flat = [name for part in parts for name in part]
        if any(len(part) == 0 for part in parts) or sorted(flat) != sorted(self.current):
            raise ReductionError(
                f"partition schema {self.settings.partitioner.name!r} must return non-empty, disjoint parts "
                f"covering the current world, got {[list(part) for part in parts]!r}"
            )

    def elapsed(self) -> float:
        return time.monotonic() - self.started_at

    def probes(self) -> int:
        """Probes decided in the whole history: the resumed log's and this call's."""
        return self.history + self.probing.counters.probes

    def emit(self, kind: str, *, candidate: Candidate | None = None, outcome: Outcome | None = None) -> None:
        if self.settings.on_progress is None:
            return
        self.settings.on_progress(
            ProgressEvent(
                kind=kind,
                size=len(self.full(self.current)),
                probes=self.probes(),
                granularity=self.granularity,
                elapsed=self.elapsed(),
                candidate=candidate,
                outcome=outcome,
            )
        )

    def write(self, event: events.Event) -> None:
        if self.log is not None:
            self.log.write(replace(event, elapsed=round(self.elapsed(), 6)))

    def result(self, *, one_minimal: bool, incomplete: str | None, failure_rate: tuple[int, int]) -> Reduction:
        settings, counters = self.settings, self.probing.counters
        notes = [*(self.log.notes if self.log is not None else []), *self.backoff_notes]
        if self.unverified:
            notes.append(
                f"not verified: {plural(self.unverified, 'single removal')} of the minimal world rejected only "
                "because the runs errored (a worker died or a probe hung), also when tried again; a resumed "
                "reduction tries again"
            )
        return Reduction(
            original=settings.elements,
            minimal=self.full(self.current),
            kept=tuple(name for name in settings.elements if name in settings.keep),
            probes=self.probes(),
            cache_hits=counters.cache_hits,
            skipped=len(counters.skipped),
            errors=counters.errors,
            steps=tuple(self.steps),
            one_minimal=one_minimal,
            incomplete_reason=incomplete,
            failure_rate=failure_rate,
            wall_time=self.elapsed(),
            partition=settings.partitioner.name,
            priority=settings.prioritizer.name,
            granularity=settings.granularity,
            deflake=settings.policy.label if self.calibration is None else f"auto:{self.probing.decider.policy.label}",
            seed=settings.seed,
            calibration=self.calibration,
            simulations=counters.simulations,
            resumed_probes=self.history,
            errored=len(counters.errored),
            notes=tuple(notes),
            rate_check=self.rate_check,
            rate_backoffs=self.backoffs,
            precondition_kept=self.precondition_kept(),
            without_precondition_kept=self.precondition_check,
            independent=self.independent,
            first_cut=self.first_cut,
        )

    def write_start(self) -> None:
        settings = self.settings
        self.write(events.Start(
            resumed=self.resumed, elements=tuple(settings.elements),
            keep=tuple(name for name in settings.elements if name in settings.keep),
            partition=settings.partitioner.name, priority=settings.prioritizer.name,
            n_partitions=settings.n_partitions, granularity=settings.granularity,
            complement_order=settings.complement_order, deflake=settings.policy.label, seed=settings.seed,
            max_probes=settings.max_probes, max_seconds=settings.max_seconds,
            failure_rate_runs=settings.failure_rate_runs, reference=settings.reference is not None))
        self.emit("start")

    def write_end(self, reduction: Reduction) -> None:
        self.write(events.End(
            minimal=tuple(reduction.minimal), size=len(reduction.minimal), original_size=len(reduction.original),
            probes=reduction.probes, simulations=reduction.simulations, resumed_probes=reduction.resumed_probes,
            cache_hits=reduction.cache_hits, skipped=reduction.skipped, errors=reduction.errors,
            errored=reduction.errored, steps=[list(step) for step in reduction.steps],
            one_minimal=reduction.one_minimal, incomplete_reason=reduction.incomplete_reason,
            failure_rate=list(reduction.failure_rate),
            rate_check=None if reduction.rate_check is None else reduction.rate_check.decision,
            rate_backoffs=reduction.rate_backoffs, wall_time=reduction.wall_time))
        self.emit("end")

    @staticmethod
    def _open_log(settings: Settings) -> ProbeLog | None:
        if settings.log is None:
            return None
        log = settings.log if isinstance(settings.log, ProbeLog) else ProbeLog(settings.log, resume=True)
        started = log.started_with()
        if started is not None and (started[0] != settings.elements or set(started[1]) != settings.keep):
            raise ReductionError(
                f"the probe log {log.path or '(in memory)'} belongs to a reduction of a different world "
                f"({len(started[0])} elements, keep={list(started[1])}); pass another log path, or move this one away"
            )
        return log
