"""Stage `shapes`: inside each kept model with several collision shapes, the shapes the failure needs
(hierarchical delta debugging: the same engine, one level down, the model's identity kept)."""

from __future__ import annotations

import dataclasses
from typing import Any

from pytest_ddenv.reduce.types import Candidate
from pytest_ddenv.scenario.probe import start_support
from pytest_ddenv.stages.context import RATE_RUNS, StageContext
from pytest_ddenv.stages.result import StageResult
from pytest_ddenv.world.model import Model, World

STAGE = "shapes"


def shape_name(model: str, index: int) -> str:
    """The element name of a model's shape: 'model#index' (index in the model's shape list, from 0)."""
    return f"{model}#{index}"


def shape_elements(world: World) -> dict[str, tuple[str, int]]:
    """element name -> (model, shape index), for every reducible model with two or more shapes."""
    return {shape_name(model.name, index): (model.name, index)
            for model in world.models if not model.keep and len(model.shapes) > 1
            for index in range(len(model.shapes))}


def with_shapes(world: World, elements: dict[str, tuple[str, int]], kept: Candidate) -> World:
    """`world` whose split models keep only the shapes named in `kept` (the other models unchanged)."""
    keep = set(kept)
    dropped: dict[str, set[int]] = {}
    for name, (model, index) in elements.items():
        if name not in keep:
            dropped.setdefault(model, set()).add(index)

    def trimmed(model: Model) -> Model:
        gone = dropped.get(model.name)
        if not gone:
            return model
        return dataclasses.replace(model, shapes=tuple(s for i, s in enumerate(model.shapes) if i not in gone))

    return dataclasses.replace(world, models=tuple(trimmed(model) for model in world.models))


def run(context: StageContext) -> StageResult:
    world = context.base
    elements = shape_elements(world)
    begin = context.budget.started()
    if not elements:
        return StageResult(STAGE, world, findings=["no model has more than one shape"])
    support = start_support(world)

    def build(candidate: Candidate) -> World:
        return with_shapes(world, elements, candidate)

    def every_model_keeps_a_shape(candidate: Candidate) -> str | None:
        kept_models = {elements[name][0] for name in candidate}
        for model in {model for model, _ in elements.values()} - kept_models:
            return f"removes every shape of '{model}' (that is removing the model, decided by the models stage)"
        if support is not None and support in {m for m, _ in elements.values()} and start_support(
                build(candidate)) != support:
            return f"removes the shape of '{support}' under the robot's start"
        return None

    reduction = context.reduce_edits(STAGE, tuple(elements), build, preconditions=(every_model_keeps_a_shape,),
                                     stage_begin=begin, rate_runs=RATE_RUNS)
    simulations = context.budget.started() - begin
    if reduction is None:
        return StageResult(STAGE, world, simulations=simulations, incomplete="budget: no probes left")
    kept = set(reduction.minimal)
    findings: list[str] = []
    details: list[dict[str, Any]] = []
    for model in world.models:
        indices = [index for name, (owner, index) in elements.items() if owner == model.name]
        if not indices:
            continue
        needed = [index for index in indices if shape_name(model.name, index) in kept]
        kinds = [model.shapes[index].kind for index in needed]
        findings.append(f"{model.name}: {len(needed)} of {len(indices)} shapes "
                        + ("" if reduction.one_minimal else "(not all decided) ") + "("
                        + ", ".join(f"#{index} {kind}" for index, kind in zip(needed, kinds, strict=True)) + ")")
        details.append({"model": model.name, "shapes": len(indices), "kept": needed})
    rate = {"failure_rate": list(reduction.failure_rate)} if reduction.failure_rate[1] else {}
    return StageResult(STAGE, build(reduction.minimal), probes=reduction.probes, simulations=simulations,
                       findings=findings, details={"models": details, "kept": list(reduction.minimal), **rate},
                       incomplete=None if reduction.one_minimal else reduction.incomplete_reason,
                       reduction=reduction)
