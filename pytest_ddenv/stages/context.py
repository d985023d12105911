"""What every stage after the model-level reduction shares: the world it starts from, the way to run the
test on a world, the deflake rule, the budget, and the log (one `ProbeLog.view` per stage).

A stage decides worlds in two ways: a set of named edits reduced by the same engine as the models
(`reduce_edits`: shapes, simplifications, differences), or one world at a time (`decide`: a start pose, a
time limit, a passing world), each run logged as a probe record of the stage, so that a resumed reduction
reuses it.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from pytest_ddenv.execution import ProbeDeadline
from pytest_ddenv.oracle.verdict import FailureReference, classify_result
from pytest_ddenv.outcome import Outcome
from pytest_ddenv.reduce import ProbeLog, ProbeObservation, Reduction, ReductionSettings, events, reduce
from pytest_ddenv.reduce.budget import StageBudget
from pytest_ddenv.reduce.deflake import ConfirmedRuns, DeflakePolicy
from pytest_ddenv.reduce.types import Candidate, Precondition, Probe
from pytest_ddenv.scenario.probe import ProbeCall, ProbeResult, make_probe, signature_record

if TYPE_CHECKING:
    from pytest_ddenv.oracle.verdict import SameFailureRule
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

RATE_RUNS = 10
"""Fresh runs (at most) with which a stage reduced by the engine compares its world's failure rate with
the world it started from (and backs off when it is significantly lower)."""
FRESH_ATTEMPTS = 1000
"""The first attempt (noise seed) of the final world's failure-rate runs: far from those of any decision."""
PASSES_RULE = ConfirmedRuns(max_runs=3, confirm=3)
"""A world "passes" when 3 of 3 runs pass (a passing world is shown by every run, not by luck)."""


def scenario_models(world: World) -> tuple[str, ...]:
    """The models the scenario itself names, in world order: an arm's table and target. No stage removes,
    moves or resizes them (the scenario would change), and the models stage keeps them out of its partitions
    (they are not candidates, as a `keep` model); a mobile robot's scenario names none."""
    scenario = world.scenario
    named = set() if scenario is None else {scenario.table, scenario.target}
    return tuple(name for name in world.names if name in named)


@dataclass
class StageContext:
    """`base`: the world the stages start from (the model-level minimal world); `call` runs the test on a
    world; `rule` decides which failures are the reference failure; `wrap` turns a probe into the driver's (it
    stops probes at the time budget's deadline)."""

    base: World
    call: ProbeCall
    reference: FailureReference
    rule: SameFailureRule
    log: ProbeLog
    policy: DeflakePolicy
    seed: int
    budget: StageBudget
    run: Run | None = None
    executor: concurrent.futures.Executor | None = None
    workers: int | None = None
    """How many probes a round keeps running at once on `executor` (`reduce(workers=...)`)."""
    wrap: Callable[[Probe], Probe] = field(default=lambda probe: probe)

    def reduce_edits(self, stage: str, elements: Sequence[str], build: Callable[[Candidate], World], *,
                     preconditions: Sequence[Precondition] = (), policy: DeflakePolicy | None = None,
                     invert: bool = False, stage_begin: int | None = None, rate_runs: int = 0) -> Reduction | None:
        """Reduce `elements` (names of edits; a candidate keeps some, `build` makes its world) with the
        engine, logged in the stage's view. `invert`: the property kept is "the world passes" (the nearest
        passing world). `rate_runs`: compare the result's failure rate with the first world's on up to this
        many fresh runs each, backing off as the models stage does (`failure_rate_runs`). None when there is
        nothing to reduce or no budget left."""
        if not elements:
            return None
        left = self.budget.left(stage_begin)
        if left is not None and left <= 0:
            return None
        probe = make_probe(self.base, self.call, self.reference, rule=self.rule, build=build)
        if invert:
            probe = _passing_probe(probe)
        settings = ReductionSettings(
            partition="model2model", priority="sequential", deflake=policy or self.policy,
            preconditions=tuple(preconditions), max_probes=left, seed=self.seed, failure_rate_runs=rate_runs,
            workers=self.workers,
        )
        reduction = reduce(tuple(elements), self.wrap(probe), settings, log=self.log.view(stage),
                           executor=self.executor)
        self.budget.decisions += reduction.probes
        return reduction

    def decide(self, stage: str, label: str, world: World, *, policy: DeflakePolicy | None = None,
               passes: bool = False, stage_begin: int | None = None) -> Decided:
        """Does `world` reproduce the failure (`passes`: does it pass) by the deflake rule? Runs attempts
        0, 1, ... of it until the rule decides, each logged under the stage with candidate [label]; a label
        already decided in the log is not run again. `Decided.verdict` is None when the budget ran out."""
        view = self.log.view(stage)
        rule = policy or (PASSES_RULE if passes else self.policy)
        known = view.decisions().get(frozenset([label]))
        if known is not None:
            return Decided(known.reproduces, known.fails, known.runs,
                           signatures=[entry[1] for entry in _logged(view, label)])
        logged = _logged(view, label)
        outcomes = [entry[0] for entry in logged]
        last: ProbeResult | None = None
        while (verdict := rule.verdict(_as_property(outcomes, passes))) is None:
            left = self.budget.left(stage_begin)
            if left is not None and left <= 0:
                return Decided(None, _count(outcomes, passes), len(outcomes), signatures=[e[1] for e in logged])
            attempt = len(outcomes)
            try:
                last = self.call(world, attempt)
            except ProbeDeadline:  # the time budget ran out: undecided, like the probe budget
                return Decided(None, _count(outcomes, passes), len(outcomes))
            except Exception as error:  # noqa: BLE001 - the pool could not run it: no verdict
                view.write(events.Probe(candidate=(label,), attempt=attempt, outcome=Outcome.ERROR.value,
                                        detail=f"{type(error).__name__}: {error}"[:300]))
                return Decided(None, _count(outcomes, passes), len(outcomes), error=str(error))
            outcome = classify_result(last.error, self.reference, self.rule)
            record = signature_record(last.error)
            signature = None if record is None else dict(record)
            view.write(events.Probe(
                kind="decide", candidate=(label,), size=1, attempt=attempt,
                seed=None if last.run is None else int(last.run.seed), outcome=outcome.value, signature=signature,
                sim_time=0.0 if last.run is None else float(last.run.sim_time),
                wall_time=0.0 if last.run is None else float(last.run.wall_time),
                detail="" if last.error is None or outcome is Outcome.FAIL else last.error.describe()[:2000]))
            if outcome is Outcome.ERROR:
                return Decided(None, _count(outcomes, passes), len(outcomes),
                               error=last.error.describe() if last.error is not None else "error")
            outcomes.append(outcome)
            logged.append((outcome, signature))
        fails = _count(outcomes, passes)
        self.budget.decisions += 1
        view.write((events.Accept if verdict else events.Reject)(candidate=(label,), reproduces=verdict, fails=fails,
                                                                 runs=len(outcomes)))
        return Decided(verdict, fails, len(outcomes), signatures=[entry[1] for entry in logged],
                       run=None if last is None else last.run)

    def measure(self, stage: str, label: str, world: World, runs: int, *, first_attempt: int = FRESH_ATTEMPTS,
                stage_begin: int | None = None) -> tuple[int, int, int]:
        """(fails, runs, errors) of `world` on `runs` fresh runs (attempts from `first_attempt`: seeds no
        decision used), logged as "failure-rate" probes of the stage (a resumed reduction reuses them); fewer
        runs when the budget runs out. ERROR runs are counted apart, not as runs."""
        view = self.log.view(stage)
        done = view.measured("failure-rate", [label])
        fails = counted = errors = 0
        for attempt in range(first_attempt, first_attempt + runs):
            outcome = done.get(attempt)
            if outcome is None:
                left = self.budget.left(stage_begin)
                if left is not None and left <= 0:
                    break
                try:
                    result = self.call(world, attempt)
                except ProbeDeadline:
                    break
                except Exception:  # noqa: BLE001 - an error is no outcome of the seed
                    errors += 1
                    continue
                outcome = classify_result(result.error, self.reference, self.rule)
                view.write(events.Probe(
                    purpose="failure-rate", candidate=(label,), size=1, attempt=attempt, outcome=outcome.value,
                    signature=signature_record(result.error),
                    sim_time=0.0 if result.run is None else float(result.run.sim_time),
                    wall_time=0.0 if result.run is None else float(result.run.wall_time)))
            if outcome is Outcome.ERROR:
                errors += 1
                continue
            counted += 1
            fails += outcome is Outcome.FAIL
        return fails, counted, errors


@dataclass
class Decided:
    """The verdict on one world: `verdict` (None: undecided, the budget ran out or a run errored), the runs
    that showed the property (`fails`) of `runs`."""

    verdict: bool | None
    fails: int
    runs: int
    error: str = ""
    signatures: list[dict[str, object] | None] = field(default_factory=list)
    run: Run | None = None


def _logged(view: ProbeLog, label: str) -> list[tuple[Outcome, dict[str, object] | None]]:
    """Outcomes and signatures of attempts 0, 1, ... of `label` already in the stage's log (no ERROR)."""
    by_attempt: dict[int, tuple[Outcome, dict[str, object] | None]] = {}
    for probe in view.probes():
        if probe.candidate == (label,) and probe.result is not Outcome.ERROR:
            by_attempt[probe.attempt] = (probe.result, None if probe.signature is None else dict(probe.signature))
    found: list[tuple[Outcome, dict[str, object] | None]] = []
    while len(found) in by_attempt:
        found.append(by_attempt[len(found)])
    return found


def _as_property(outcomes: Sequence[Outcome], passes: bool) -> list[Outcome]:
    """The outcomes as the rule reads them: FAIL = the property holds (reproduces f, or passes)."""
    if not passes:
        return list(outcomes)
    return [Outcome.FAIL if outcome is Outcome.PASS else Outcome.PASS for outcome in outcomes]


def _count(outcomes: Sequence[Outcome], passes: bool) -> int:
    return sum(1 for outcome in _as_property(outcomes, passes) if outcome is Outcome.FAIL)


def _passing_probe(probe: Probe) -> Probe:
    """The probe of the property "the world passes": PASS reads as FAIL (the property holds), FAIL and
    another failure as PASS; ERROR stays ERROR."""

    def passing(candidate: Candidate, attempt: int) -> ProbeObservation:
        observed = probe(candidate, attempt)
        if observed.outcome is Outcome.ERROR:
            return observed
        flipped = Outcome.FAIL if observed.outcome is Outcome.PASS else Outcome.PASS
        return ProbeObservation(outcome=flipped, trace=None, signature=observed.signature, seed=observed.seed,
                           sim_time=observed.sim_time, wall_time=observed.wall_time, detail=observed.detail)

    return passing
