"""The stages after the model-level reduction (``--ddenv-stages``): inside models (`shapes`), simpler values
(`attributes`), a shorter scenario (`time`), what each culprit does (`explain`) and the nearest passing world
(`passing`). See docs/algorithm.md, "After the models".

They start from the model-level minimal world and never change it: their result is a further world
(`simplified.yaml`) and a passing one (`passing.yaml`). Each is logged in the reduction's `runs.jsonl` under
its own ``stage`` key (so it resumes), and all of them share one simulation budget.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.reduce.deflake import CalibratedReruns, DeflakePolicy, FixedReruns
from pytest_ddenv.stages import attributes, explain, passing, shapes, shorten
from pytest_ddenv.stages.context import FRESH_ATTEMPTS, Budget, StageContext
from pytest_ddenv.stages.result import StageResult

if TYPE_CHECKING:
    from pytest_ddenv.reduce import Reduction
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world import World

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
NOISE = 0.2
"""A stage's world whose failures on its fresh runs would be this unlikely at the minimal world's rate (about
one standard deviation, one-sided) fails less often beyond the noise of those runs: the stage is reverted."""
PASSING_RESERVE = 6
"""Simulations kept for the nearest passing world while the stages before it run."""


class StagesError(ValueError):
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
    or not measured); `passing`: the nearest passing world, if found."""

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
    passing: World | None = None
    simulations: int = 0
    probes: int = 0
    budget: int | None = None

    def result(self, stage: str) -> StageResult | None:
        return next((result for result in self.results if result.stage == stage), None)

    def to_dict(self) -> dict[str, Any]:
        return {"stages": list(self.stages), "probes": self.probes, "simulations": self.simulations,
                "budget": self.budget, "changed": self.changed,
                "final_failure_rate": None if self.final_rate is None else list(self.final_rate),
                "final_rate_below": self.rate_below, "final_rate_errors": self.final_errors,
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
    budget.reserve = (FINAL_RATE_RUNS if simulating else 0) + (PASSING_RESERVE if "passing" in stages else 0)
    world = _simplify(context, simulating, models, outcome, minimal_run, folder)
    budget.share = None
    outcome.final, outcome.changed = world, world != context.base
    budget.reserve = PASSING_RESERVE if "passing" in stages else 0
    if outcome.final_rate is not None and outcome.minimal_rate is not None:
        outcome.rate_below = rate_drops(outcome.final_rate, outcome.minimal_rate)
    final_context = dataclasses.replace(context, base=world)
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
        found = _record(outcome, passing.run(final_context, explained, kept, final_is_minimal=not outcome.changed,
                                             search=not log_only), budget.decisions - decisions)
        if found.details.get("found"):
            outcome.passing = found.world
    outcome.simulations = budget.started() - begin
    outcome.probes = budget.decisions
    return outcome


def _record(outcome: StagesOutcome, result: StageResult, decisions: int) -> StageResult:
    """`result` (which made `decisions` decisions) added to the outcome."""
    result.probes = decisions
    outcome.results.append(result)
    return result


def _simplify(context: StageContext, simulating: Sequence[str], models: Reduction, outcome: StagesOutcome,
              minimal_run: Run | None, folder: Path) -> World:
    """The stages that change the world (shapes, attributes, time), each from the world the one before kept;
    a stage's world is kept only if it fails about as often as the minimal world on fresh runs."""
    budget, base = context.budget, context.base
    world = base
    reference = models.failure_rate
    if simulating:  # the minimal world's rate, on fresh runs measured as the stages' worlds will be
        reserve, budget.reserve = budget.reserve, 0
        fails, runs, _ = _rate(context, "minimal world", base, len(SIMULATING))
        budget.reserve = reserve
        reference = (reference[0] + fails, reference[1] + runs)
        outcome.minimal_rate = reference
    for number, stage in enumerate(simulating):
        decisions = budget.decisions
        left = budget.left()
        budget.share = None if left is None else left // (len(simulating) - number)  # the rest goes on
        here = dataclasses.replace(context, base=world)
        if stage == "shapes":
            made = shapes.run(here)
        elif stage == "attributes":
            made = attributes.run(here, folder / "meshes")
        else:
            made = shorten.run(dataclasses.replace(here, run=minimal_run))
        result = _record(outcome, made, budget.decisions - decisions)
        if result.world == world:
            continue
        reserve, budget.reserve = budget.reserve, budget.reserve - FINAL_RATE_RUNS
        fails, runs, errors = _rate(context, f"{stage} world", result.world, number)
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
    return world


def _rate(context: StageContext, label: str, world: World, number: int) -> tuple[int, int, int]:
    """(fails, runs, errors) of `world` on fresh runs: 5, then 10 unless each of the first 5 failed."""
    first = FRESH_ATTEMPTS + 100 * number
    fails, runs, errors = context.measure("rates", label, world, FINAL_RATE_RUNS // 2, first_attempt=first)
    if errors or fails == runs:
        return fails, runs, errors
    more = context.measure("rates", label, world, FINAL_RATE_RUNS - FINAL_RATE_RUNS // 2,
                           first_attempt=first + FINAL_RATE_RUNS // 2)
    return fails + more[0], runs + more[1], errors + more[2]


def rate_drops(rate: tuple[int, int], minimal: tuple[int, int]) -> bool:
    """A stage's world fails less often than the minimal world beyond the noise of its runs: at the minimal
    world's rate (estimated as (fails + 0.5) / (runs + 1), never 0 or 1), `rate[1]` runs would show as few
    failures as `rate[0]` with probability below `NOISE` (binomial tail), or the rate is significantly below
    the minimal world's (Fisher, one-sided, 5 %)."""
    if rate[1] == 0 or minimal[1] == 0:
        return False
    from scipy.stats import binom

    expected = (minimal[0] + 0.5) / (minimal[1] + 1.0)
    return bool(binom.cdf(rate[0], rate[1], expected) < NOISE) or _significantly_below(rate, minimal)


def _significantly_below(final: tuple[int, int], minimal: tuple[int, int]) -> bool:
    """The final world fails significantly less often than the minimal one (Fisher, one-sided, 5 %)."""
    if final[1] == 0 or minimal[1] == 0:
        return False
    from scipy.stats import fisher_exact

    table = [[final[0], final[1] - final[0]], [minimal[0], minimal[1] - minimal[0]]]
    return bool(fisher_exact(table, alternative="less").pvalue < 0.05)


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


__all__ = ["DEFAULT_STAGES", "STAGES", "Budget", "StageContext", "StageResult", "StagesError", "StagesOutcome",
           "parse_stages", "run_stages", "stage_budget", "stage_policy"]
