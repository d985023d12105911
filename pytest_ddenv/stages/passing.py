"""Stage `passing`: the nearest passing world, a world that passes and differs as little as possible from
the final failing one; together they bracket the failure.

The differences are the changes the earlier stages found to break the failure: removing a model of the
final world, removing one of its shapes, applying a simplification that broke it. A single difference
the log already shows passing on this very world costs nothing; otherwise the single differences are tried
(those the log saw passing first, `MAX_SINGLES` at most), and if none passes, delta debugging over the
differences (the engine, reducing the set of applied differences while the world passes: a 1-minimal
difference) finds the pair, after checking that applying all of them passes. A world "passes" when 3 of 3
runs pass.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pytest_ddenv.reduce.types import Candidate
from pytest_ddenv.scenario.probe import start_support
from pytest_ddenv.stages.context import Decided, StageContext, scenario_models
from pytest_ddenv.stages.result import StageResult
from pytest_ddenv.world.model import World

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run

STAGE = "passing"
MAX_SINGLES = 3


def differences(final: World, attributes: StageResult | None) -> dict[str, Callable[[World], World]]:
    """description -> change of `final`, in the order tried: simplifications, shapes, models."""
    found: dict[str, Callable[[World], World]] = dict(attributes.differences) if attributes is not None else {}
    fixed = {start_support(final), *scenario_models(final)}  # removing them changes the scenario, not the world
    for model in final.models:
        if model.keep or len(model.shapes) < 2:
            continue
        for index, shape in enumerate(model.shapes):
            found[f"without shape #{index} ({shape.kind}) of {model.name}"] = _without_shape(model.name, index)
    for model in final.models:
        if not model.keep and model.name not in fixed:
            found[f"without {model.name}"] = _without_model(model.name)
    return found


def _without_model(name: str) -> Callable[[World], World]:
    return lambda world: world.without([name])


def _without_shape(name: str, index: int) -> Callable[[World], World]:
    def change(world: World) -> World:
        model = world.model(name)
        shapes = tuple(shape for i, shape in enumerate(model.shapes) if i != index)
        return dataclasses.replace(world, models=tuple(
            dataclasses.replace(m, shapes=shapes) if m.name == name else m for m in world.models))

    return change


def applied(final: World, changes: dict[str, Callable[[World], World]], chosen: Candidate) -> World:
    """`final` with the chosen changes, in a fixed order: simplifications and shape removals first (by
    shape index, from the last), model removals last, so that each change finds what it changes."""
    names = set(chosen)
    ordered = [name for name in changes if name in names]
    shape_changes = sorted((name for name in ordered if name.startswith("without shape #")),
                           key=lambda name: -int(name.split("#")[1].split(" ")[0]))
    models = [name for name in ordered if name.startswith("without ") and name not in shape_changes]
    others = [name for name in ordered if name not in shape_changes and name not in models]
    world = final
    for name in [*others, *shape_changes, *models]:
        world = changes[name](world)
    return world


def run(context: StageContext, explained: StageResult | None, attributes: StageResult | None,
        final_is_minimal: bool, *, search: bool = True) -> StageResult:
    """The nearest passing world of `context.base` (the final world); `search` False: from the log only."""
    final = context.base
    begin = context.budget.started()
    changes = differences(final, attributes)
    if not changes:
        return StageResult(STAGE, final, findings=["no difference to try (no model can be removed)"])
    known_passing = _known_passing(explained)
    if final_is_minimal:  # the log ran exactly these worlds: no new simulation
        for name, counts in known_passing:
            if counts["pass"] >= 1 and counts["same"] == 0 and counts["other"] == 0:
                return _found(STAGE, context, final, changes, (name,), counts["pass"], counts["pass"], begin,
                              source="log")
    if not search:
        return _none(context, begin, None, "no passing world in the log next to the minimal world (ask for the "
                     "passing stage, --ddenv-stages ...,passing, to search for one)")
    order = [name for name, _ in known_passing if name in changes]
    order += [name for name in changes if name not in order]
    for name in order[:MAX_SINGLES]:
        decided = context.decide(STAGE, name, changes[name](final), passes=True, stage_begin=begin)
        if decided.verdict:
            return _found(STAGE, context, final, changes, (name,), decided.fails, decided.runs, begin,
                          run=decided.run)
        if decided.verdict is None:
            return _none(context, begin, "budget: no probes left" if not decided.error else f"error: {decided.error}")
    everything = tuple(changes)
    decided = context.decide(STAGE, "all differences", applied(final, changes, everything), passes=True,
                             stage_begin=begin)
    if decided.verdict is None:
        return _none(context, begin, "budget: no probes left" if not decided.error else f"error: {decided.error}")
    if not decided.verdict:
        return _none(context, begin, None, f"no passing world found: even with every difference applied "
                     f"({len(everything)}) the test passed in only {decided.fails} of {decided.runs} runs")
    reduction = context.reduce_edits(STAGE, everything, lambda chosen: applied(final, changes, chosen),
                                     invert=True, stage_begin=begin)
    if reduction is None:
        return _found(STAGE, context, final, changes, everything, decided.fails, decided.runs, begin,
                      incomplete="budget: no probes left", run=decided.run)
    verdict: Decided = context.decide(STAGE, " + ".join(reduction.minimal), applied(final, changes, reduction.minimal),
                                      passes=True, stage_begin=begin)
    if not verdict.verdict:  # its check did not pass (or could not run): the world shown passing is the answer
        why = ("budget: no probes left" if verdict.verdict is None else
               f"{' + '.join(reduction.minimal)} passed only {verdict.fails} of {verdict.runs} runs when checked")
        return _found(STAGE, context, final, changes, everything, decided.fails, decided.runs, begin,
                      incomplete=why, run=decided.run)
    return _found(STAGE, context, final, changes, reduction.minimal, verdict.fails, verdict.runs, begin,
                  incomplete=None if reduction.one_minimal else reduction.incomplete_reason, run=verdict.run)


def _known_passing(explained: StageResult | None) -> list[tuple[str, dict[str, Any]]]:
    """(difference name, counts) of the explained elements whose removal passed in the log, most passes
    first."""
    if explained is None:
        return []
    found: list[tuple[str, dict[str, Any]]] = []
    for entry in explained.details.get("elements", []):
        if entry.get("kind") == "model" and entry.get("pass", 0) > 0 and entry.get("source", "").startswith("log"):
            found.append((f"without {entry['element']}", entry))
    return sorted(found, key=lambda item: (-item[1]["pass"], item[1]["same"] + item[1]["other"]))


def _found(stage: str, context: StageContext, final: World, changes: dict[str, Callable[[World], World]],
           chosen: Candidate, passes: int, runs: int, begin: int, *, source: str = "simulated",
           incomplete: str | None = None, run: Run | None = None) -> StageResult:
    world = applied(final, changes, chosen)
    text = "; ".join(chosen)
    origin = ", from the log" if source == "log" else ""
    findings = [f"nearest passing world: {text} (passes {passes} of {runs} runs{origin})"]
    return StageResult(stage, world, simulations=context.budget.started() - begin, findings=findings,
                       details={"difference": list(chosen), "passes": passes, "runs": runs, "source": source,
                                "found": True}, incomplete=incomplete, run=run)


def _none(context: StageContext, begin: int, incomplete: str | None, text: str = "") -> StageResult:
    return StageResult(STAGE, context.base, simulations=context.budget.started() - begin,
                       findings=[text or f"no passing world found ({incomplete})"],
                       details={"found": False}, incomplete=incomplete)
