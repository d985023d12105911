"""Is the world the stages left still 1-minimal? The model-level reduction showed that every model of the
minimal world is needed; the stages then changed those models (fewer shapes, rounder values, a later start),
which can make one of them unnecessary. So, after them, each single model of the final world is removed and
the world decided by the deflake rule, as the models stage decides a candidate (same oracle, same rule),
each run logged under this check's own stage key and counted, within the stages' budget. The result says
"1-minimal", "not 1-minimal" (which removal still fails the same way) or "not shown 1-minimal" (what the
budget or an error left undecided); it never says more than the runs showed."""

from __future__ import annotations

import hashlib
from typing import Any

from pytest_ddenv.scenario.probe import start_support
from pytest_ddenv.stages.context import StageContext, scenario_models
from pytest_ddenv.stages.result import StageResult

STAGE = "one-minimal"
"""The check's key in the run log and its name in the report."""


def run(context: StageContext) -> StageResult:
    """Decide "`context.base` without each of its models" (not the models marked `keep`, nor the one under
    the robot's start, nor an arm's table and target: the models stage keeps them too)."""
    world = context.base
    begin = context.budget.started()
    support = start_support(world)
    named = scenario_models(world)
    digest = hashlib.sha1(world.to_yaml().encode()).hexdigest()[:10]  # a resumed log answers for this world only
    needed: list[str] = []
    still_fails: list[str] = []
    undecided: list[str] = []
    findings: list[str] = []
    for model in world.models:
        if model.name in named and not model.keep:
            findings.append(f"without {model.name}: not run (the scenario names it: kept, as in the models stage)")
            continue
        if model.keep or model.name == support:
            why = "marked keep" if model.keep else "under the robot's start"
            findings.append(f"without {model.name}: not run ({why}: kept by a precondition, as in the models stage)")
            continue
        decided = context.decide(STAGE, f"without {model.name} (world {digest})", world.without([model.name]),
                                 stage_begin=begin)
        runs = f"{decided.fails} of {decided.runs} runs failed the same way"
        if decided.verdict is None:
            undecided.append(model.name)
            why = f"an error: {decided.error}" if decided.error else "the budget ran out"
            findings.append(f"without {model.name}: not decided ({why}; {runs})")
        elif decided.verdict:
            still_fails.append(model.name)
            findings.append(f"without {model.name}: still the same failure ({runs}): not needed any more")
        else:
            needed.append(model.name)
            findings.append(f"without {model.name}: not the same failure ({runs}): needed")
    one_minimal = False if still_fails else None if undecided else True
    if still_fails:
        verdict = (f"the simplified world is NOT 1-minimal: it still fails the same way without "
                   f"{', '.join(still_fails)}")
    elif undecided:
        verdict = f"the simplified world is not shown 1-minimal: {len(undecided)} removal(s) not decided"
    else:
        verdict = "the simplified world is 1-minimal: without any one of its models it no longer fails the same way"
    details: dict[str, Any] = {"one_minimal": one_minimal, "needed": needed, "not_needed": still_fails,
                               "undecided": undecided}
    return StageResult(STAGE, world, simulations=context.budget.started() - begin, findings=[verdict, *findings],
                       details=details, incomplete=f"{len(undecided)} removal(s) not decided" if undecided else None)
