"""The stages after the model-level reduction (``--ddenv-stages``): inside models (`shapes`), simpler values
(`attributes`), a shorter scenario (`time`), what each culprit does (`explain`) and the nearest passing world
(`passing`). See docs/algorithm.md, "After the models".

They start from the model-level minimal world and never change it: their result is a further world
(`simplified.yaml`), checked to be still 1-minimal (`minimality`), and a passing one (`passing.yaml`, searched
with the original start and time limit). Each is logged in the reduction's `runs.jsonl` under its own
``stage`` key (so it resumes), and all of them share one simulation budget.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.reduce.budget import StageBudget
from pytest_ddenv.reduce.deflake import CalibratedReruns, DeflakePolicy, FixedReruns
from pytest_ddenv.reduce.rates import rate_drops
from pytest_ddenv.scenario.probe import start_support
from pytest_ddenv.stages import attributes, explain, minimality, passing, runs_kept, shapes, shorten, structure
from pytest_ddenv.stages.context import FRESH_ATTEMPTS, StageContext, scenario_models
from pytest_ddenv.stages.result import StageResult

if TYPE_CHECKING:
    from pytest_ddenv.reduce import Reduction
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

STAGES: tuple[str, ...] = ("models", "shapes", "attributes", "time", "explain", "passing")
DEFAULT_STAGES: tuple[str, ...] = ("models", "explain", "passing")
"""On by default, and then read from the log only (no simulation): what each culprit does, and a passing
world when the log ran one next to the minimal world. Chosen explicitly, they simulate what the log lacks."""
SIMULATING = ("shapes", "attributes", "time")
"""The stages that change the world (each simulates candidates)."""
BUDGET_FACTOR = 2
"""Without `stage_probes`, the stages together start at most this many times the model-level simulations."""
FINAL_RATE_RUNS = 10
"""Fresh runs (at most) of the world each stage that changes it leaves, compared with the minimal world's:
a stage whose world fails significantly less often is reverted, so the final world never overstates. They
are kept out of the budget of the stage itself, so that the rate is always measured."""
PASSING_RESERVE = 6
"""Simulations kept for the nearest passing world while the stages before it run."""
CHECK_RESERVE = 3
"""Simulations kept per model it removes (10 at most) for the check that the world the stages changed is
still 1-minimal (`minimality`)."""


class StagesError(DdenvError, ValueError):
    """A stage list that names an unknown stage."""


def parse_stages(value: str | Sequence[str]) -> tuple[str, ...]:
    """'models,shapes,...' or a list, in any order; 'all' = every stage; 'models' is always included.
    Returned in the order the stages run."""
    items = [part.strip() for part in value.split(",")] if isinstance(value, str) else list(value)
    if not items or any(not isinstance(item, str) or not item for item in items):
        raise StagesError(f"expected a comma-separated list of stages ({', '.join(STAGES)}) or 'all', got {value!r}")
    if items == ["all"]:
        return STAGES
    unknown = [item for item in items if item not in STAGES]
    if unknown:
        raise StagesError(f"unknown stage {unknown[0]!r}; valid stages: {', '.join(STAGES)} (or 'all')")
    return tuple(stage for stage in STAGES if stage in items or stage == "models")


@dataclass
class StagesOutcome:
    """What the stages after the models found. `final`: the world after shapes, attributes and time (the
    minimal world if they changed nothing); `final_rate`: its failure rate on fresh runs (None: unchanged
    or not measured); `final_one_minimal`: whether it is 1-minimal (None: not shown); `passing`: the
    nearest passing world, if found (with the original start and time limit). `final_run` and
    `passing_run`: a failing run of `final` and a passing run of `passing` simulated now, for the pictures
    (None: none was)."""

    stages: tuple[str, ...]
    results: list[StageResult] = field(default_factory=list)
    final: World | None = None
    changed: bool = False
    final_rate: tuple[int, int] | None = None
    final_errors: int = 0
    minimal_rate: tuple[int, int] | None = None
    """The minimal world's failure rate the stages compare with: its fresh runs of the models stage and
    as many more as a stage's world gets."""
    rate_below: bool = False
    final_one_minimal: bool | None = None
    kept: list[str] = field(default_factory=list)
    """The stages whose world was kept (changed, and not reverted), in order: what made `final`."""
    passing: World | None = None
    simulations: int = 0
    probes: int = 0
    budget: int | None = None
    final_run: Run | None = None
    passing_run: Run | None = None

    def result(self, stage: str) -> StageResult | None:
        return next((result for result in self.results if result.stage == stage), None)

    def to_dict(self) -> dict[str, Any]:
        return {"stages": list(self.stages), "probes": self.probes, "simulations": self.simulations,
                "budget": self.budget, "changed": self.changed,
                "final_failure_rate": None if self.final_rate is None else list(self.final_rate),
                "final_rate_below": self.rate_below, "final_rate_errors": self.final_errors,
                "final_one_minimal": self.final_one_minimal,
                "minimal_failure_rate": None if self.minimal_rate is None else list(self.minimal_rate),
                "results": [result.to_dict() for result in self.results]}


def run_stages(stages: Sequence[str], context: StageContext, models: Reduction, *, minimal_run: Run | None,
               folder: Path, log_only: bool = False) -> StagesOutcome:
    """Run the chosen stages after the model-level reduction `models`, from `context.base` (its minimal
    world); `folder` receives files a stage makes (convex hulls). `log_only` (the default stages, not
    chosen by the user): explain and passing answer from the log and simulate nothing."""
    outcome = StagesOutcome(tuple(stages), budget=context.budget.limit)
    budget = context.budget
    begin = budget.started()
    simulating = [stage for stage in SIMULATING if stage in stages]
    passing_reserve = PASSING_RESERVE if "passing" in stages else 0
    fixed = {start_support(context.base), *scenario_models(context.base)}  # the check removes every other model
    check_reserve = min(10, CHECK_RESERVE * sum(not m.keep and m.name not in fixed for m in context.base.models))
    budget.reserve = (FINAL_RATE_RUNS + check_reserve if simulating else 0) + passing_reserve
    world = _simplify(context, simulating, models, outcome, minimal_run, folder)
    budget.share = None
    outcome.final, outcome.changed = world, world != context.base
    budget.reserve = passing_reserve
    if outcome.final_rate is not None and outcome.minimal_rate is not None:
        outcome.rate_below = rate_drops(outcome.final_rate, outcome.minimal_rate)
    outcome.final_one_minimal = models.one_minimal
    if outcome.changed:  # the stages changed the models: are they all still needed?
        decisions = budget.decisions
        checked = _record(outcome, minimality.run(dataclasses.replace(context, base=world)),
                          budget.decisions - decisions)
        outcome.final_one_minimal = checked.details["one_minimal"]
    # explain and passing ask what the models do, under the scenario the failure was found with: a shorter
    # start and time limit (the time stage) would make a passing world fail for want of time
    searched = _with_scenario(world, context.base)
    final_context = dataclasses.replace(context, base=searched)
    explained = None
    if "explain" in stages:
        decisions = budget.decisions
        shaped = outcome.result("shapes")
        kept_shapes = None if shaped is None or shaped.details.get("reverted") else shaped
        explained = _record(outcome, explain.run(final_context, models, kept_shapes, simulate=not log_only),
                            budget.decisions - decisions)
    if "passing" in stages:
        budget.reserve = 0
        decisions = budget.decisions
        simplified = outcome.result("attributes")
        kept = None if simplified is None or simplified.details.get("reverted") else simplified
        found = _record(outcome, passing.run(final_context, explained, kept, final_is_minimal=searched == context.base,
                                             search=not log_only), budget.decisions - decisions)
        if searched != world:
            found.findings.append("searched with the original start and time limit (not the time stage's)")
        if found.details.get("found"):
            outcome.passing, outcome.passing_run = found.world, found.run
    outcome.simulations = budget.started() - begin
    outcome.probes = budget.decisions
    return outcome


def _with_scenario(world: World, original: World) -> World:
    """`world` with the scenario (start, time limit) of `original`."""
    return world if world.scenario == original.scenario else dataclasses.replace(world, scenario=original.scenario)


def _record(outcome: StagesOutcome, result: StageResult, decisions: int) -> StageResult:
    """`result` (which made `decisions` decisions) added to the outcome."""
    result.probes = decisions
    outcome.results.append(result)
    return result


def _simplify(context: StageContext, simulating: Sequence[str], models: Reduction, outcome: StagesOutcome,
              minimal_run: Run | None, folder: Path) -> World:
    """The stages that change the world (shapes, attributes, time), each from the world the one before kept;
    a stage's world is kept only if it fails about as often as the minimal world on fresh runs. Shapes and
    attributes may not change the world's structure (`structure`); the time stage searches along a failing
    run of the world it starts from."""
    budget, base = context.budget, context.base
    world = base
    reference = models.failure_rate
    shown = minimal_run  # a run of `world` (failing when one was simulated here) to take paths and pictures from
    if simulating:  # the minimal world's rate, on fresh runs measured as the stages' worlds will be
        reserve, budget.reserve = budget.reserve, 0
        fails, runs, _, failing = _rate(context, "minimal world", base, len(SIMULATING))
        budget.reserve = reserve
        reference = (reference[0] + fails, reference[1] + runs)
        outcome.minimal_rate = reference
        shown = failing or shown
    touched = structure.touched_at_failure(context.log.probes(), base.names) | structure.touched_at_failure(
        context.log.view("rates").probes(), ["minimal world"])
    for number, stage in enumerate(simulating):
        decisions = budget.decisions
        left = budget.left()
        budget.share = None if left is None else left // (len(simulating) - number)  # the rest goes on
        here = dataclasses.replace(context, base=world)
        kept_apart = dataclasses.replace(here, wrap=structure.touching_only_wrap(here.wrap, touched), run=shown)
        if stage == "shapes":
            made = shapes.run(kept_apart)
        elif stage == "attributes":
            made = attributes.run(kept_apart, folder / "meshes")
        else:
            made = shorten.run(dataclasses.replace(here, run=shown))
        result = _record(outcome, made, budget.decisions - decisions)
        if result.world == world:
            continue
        reserve, budget.reserve = budget.reserve, budget.reserve - FINAL_RATE_RUNS
        fails, runs, errors, failing = _rate(context, f"{stage} world", result.world, number)
        budget.reserve = reserve
        result.details["failure_rate"] = [fails, runs]
        if errors or runs == 0 or rate_drops((fails, runs), reference):
            why = f"{errors} of its runs errored" if errors else (
                "its failure rate could not be measured (the budget ran out)" if runs == 0 else
                f"it fails {fails}/{runs} fresh runs, less often than the minimal world's "
                f"{reference[0]}/{reference[1]} beyond the noise of {runs} runs")
            result.findings.append(f"reverted: {why}; the stages go on from the world before this stage")
            result.details["reverted"] = True
            continue
        world, outcome.final_rate, outcome.final_errors = result.world, (fails, runs), errors
        shown = failing
        outcome.kept.append(stage)
    if world != base:
        outcome.final_run = shown
    return world


def _rate(context: StageContext, label: str, world: World, number: int) -> tuple[int, int, int, Run | None]:
    """(fails, runs, errors) of `world` on fresh runs: 5, then 10 unless each of the first 5 failed; and one
    of those runs that failed the same way (None: none simulated now)."""
    first = FRESH_ATTEMPTS + 100 * number
    fails, runs, errors, failing = runs_kept.measure(context, "rates", label, world, FINAL_RATE_RUNS // 2,
                                                     first_attempt=first)
    if errors or fails == runs:
        return fails, runs, errors, failing
    more = runs_kept.measure(context, "rates", label, world, FINAL_RATE_RUNS - FINAL_RATE_RUNS // 2,
                             first_attempt=first + FINAL_RATE_RUNS // 2)
    return fails + more[0], runs + more[1], errors + more[2], failing or more[3]


def stage_policy(policy: DeflakePolicy, models: Reduction) -> DeflakePolicy:
    """The deflake rule of the stages: the rule the models stage used (`deflake="auto"`: the one it
    calibrated; uncalibrated: 3 re-runs)."""
    if isinstance(policy, CalibratedReruns):
        return policy.rule_for(*models.calibration) if models.calibration is not None else FixedReruns(3)
    return policy


def stage_budget(model_simulations: int, stage_probes: int | None,
                 max_probes_left: int | None) -> tuple[int | None, int | None]:
    """(limit of all the stages, limit per stage): as many simulations as the model-level reduction started
    twice over (the stages at most triple the cost of a reduction) unless `stage_probes` sets a per-stage limit, within
    what `max_probes` leaves."""
    limit: int | None = None if stage_probes is not None else max(0, BUDGET_FACTOR * model_simulations)
    if max_probes_left is not None:
        limit = max_probes_left if limit is None else min(limit, max_probes_left)
    return limit, stage_probes


Budget = StageBudget
"""The old name of `StageBudget`, kept for one release."""

__all__ = ["DEFAULT_STAGES", "STAGES", "Budget", "StageBudget", "StageContext", "StageResult", "StagesError",
           "StagesOutcome", "parse_stages", "run_stages", "scenario_models", "stage_budget", "stage_policy"]
