"""Stage `attributes`: simplify what the kept models are toward plain values, keeping a change only if the
failure still reproduces.

Each simplification is an element of a delta-debugging reduction (the engine of the models, over names
such as 'asphalt_plane:friction'): a candidate keeps some original values and applies every other
simplification, so the 1-minimal result keeps exactly the original values the failure needs, each shown
by a probe ("the failure needs mu = 100 on asphalt_plane"). Simplifications: friction to 1, restitution to
0, dynamic to static (never the reverse), mass to the default (1 kg, what a model without `mass` gets), a
mesh to its bounding box (then, in the next pass, to its convex hull), a position, yaw or size to a round
value. Values are rounded along a ladder (1 m, 0.5 m, 0.1 m; 90, 15, 5 degrees): a rounding that broke the
failure is tried again one rung finer in the next pass, at most `PASSES` passes, so the number of probes is
bounded and the result is the roundest value that still fails.

A simpler world must keep the cause (`structure`): no rung is coarser than a model's gap to its nearest
neighbour, and a candidate that changes how two models stand to each other (overlap, touch, a gap narrower or
wider than the robot) is refused before it is simulated and reported as a different structure.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pytest_ddenv.reduce.types import Candidate
from pytest_ddenv.scenario.probe import start_support
from pytest_ddenv.stages.context import RATE_RUNS, StageContext, scenario_models
from pytest_ddenv.stages.result import StageResult
from pytest_ddenv.stages.structure import keeps_structure, nearest_gaps
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.meshes import load_mesh
from pytest_ddenv.world.model import Model, Pose, Shape, World

STAGE = "attributes"
PASSES = 3
LENGTHS = (1.0, 0.5, 0.1)
"""Metres: the rungs of the rounding ladder of positions and sizes."""
ANGLES = (math.pi / 2, math.pi / 12, math.pi / 36)
"""Radians (90, 15, 5 degrees): the rungs of the rounding ladder of yaw."""
MESH_STEPS = ("box", "hull")


@dataclass(frozen=True)
class Proposal:
    """One simplification of one model: element `name` ('model:attribute'), shown as `before` -> `after`."""

    name: str
    model: str
    attribute: str
    before: str
    after: str
    apply: Callable[[Model], Model]
    rung: int = 0
    """The ladder rung this proposal rounds to (the next pass tries rung + 1 if it broke the failure)."""


def _rounded(value: float, step: float, *, positive: bool = False) -> float:
    result = round(value / step) * step
    result = round(result, 9)
    if positive and result <= 0:
        result = step
    return result


def _number(value: float) -> str:
    return f"{value:.4g}"


def _degrees(value: float) -> str:
    return f"{math.degrees(value):.4g} deg"


def _ladder_proposal(model: Model, attribute: str, rung_from: int, get: Callable[[Model], float],
                     put: Callable[[Model, float], Model], steps: tuple[float, ...], *, positive: bool = False,
                     shown: Callable[[float], str] = _number, largest: float = math.inf) -> Proposal | None:
    """The first rung from `rung_from`, no coarser than `largest`, that changes the value (None: the value is
    round at every such rung)."""
    value = get(model)
    for rung in range(rung_from, len(steps)):
        if steps[rung] > largest:
            continue
        target = _rounded(value, steps[rung], positive=positive)
        if abs(target - value) > 1e-9:
            return Proposal(f"{model.name}:{attribute}", model.name, attribute, shown(value), shown(target),
                            _setting(put, target), rung)
    return None


def _setting(put: Callable[[Model, float], Model], value: float) -> Callable[[Model], Model]:
    return lambda model: put(model, value)


def _pose_get(key: str) -> Callable[[Model], float]:
    return lambda model: float(getattr(model.pose, key))


def _pose_put(key: str) -> Callable[[Model, float], Model]:
    return lambda model, value: dataclasses.replace(model, pose=dataclasses.replace(model.pose, **{key: value}))


def _shape_rounding(index: int, step: float) -> Callable[[Model], Model]:
    """Round every dimension of shape `index` to `step`."""

    def change(model: Model) -> Model:
        shapes = list(model.shapes)
        shapes[index] = _round_shape(shapes[index], step)
        return dataclasses.replace(model, shapes=tuple(shapes))

    return change


def _round_size(value: float, step: float) -> float:
    """A dimension rounded to `step`, unless the step is larger than the dimension (a 0.2 m wall does not
    become 1 m thick: it waits for a finer rung)."""
    return value if step > value else _rounded(value, step, positive=True)


def _round_shape(shape: Shape, step: float) -> Shape:
    changes: dict[str, Any] = {}
    if shape.size is not None:
        changes["size"] = tuple(_round_size(v, step) for v in shape.size)
    if shape.radius is not None:
        changes["radius"] = _round_size(shape.radius, step)
    if shape.length is not None:
        changes["length"] = _round_size(shape.length, step)
    return dataclasses.replace(shape, **changes)


def _dimensions(shape: Shape) -> str:
    values = [*(shape.size or ()), *((shape.radius,) if shape.radius is not None else ()),
              *((shape.length,) if shape.length is not None else ())]
    return " x ".join(_number(float(v)) for v in values)


def _size_proposal(model: Model, index: int, rung_from: int, largest: float = math.inf) -> Proposal | None:
    shape = model.shapes[index]
    if shape.kind not in ("box", "cylinder", "sphere", "capsule"):
        return None
    for rung in range(rung_from, len(LENGTHS)):
        if LENGTHS[rung] > largest:
            continue
        simpler = _round_shape(shape, LENGTHS[rung])
        if simpler != shape:
            return Proposal(f"{model.name}:size#{index}", model.name, f"size#{index}", _dimensions(shape),
                            _dimensions(simpler), _shape_rounding(index, LENGTHS[rung]), rung)
    return None


def mesh_as(shape: Shape, step: str, source: str | None, folder: Path) -> Shape:
    """A mesh shape as its bounding box ("box") or as its convex hull ("hull", written to `folder`)."""
    mesh: Any = load_mesh(resolve_mesh_path(shape.mesh, source), shape.scale)
    if step == "box":
        low, high = np.asarray(mesh.bounds, dtype=float)
        centre = (low + high) / 2.0
        size = tuple(float(max(v, 1e-3)) for v in high - low)
        offset = Pose(float(centre[0]), float(centre[1]), float(centre[2]))
        return Shape("box", size=size, pose=shape.pose.compose(offset))  # type: ignore[arg-type]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"hull-{abs(hash((shape.mesh, shape.scale))) % 10**10}.obj"
    if not path.exists():
        mesh.convex_hull.export(path)
    return Shape("mesh", mesh=str(path.resolve()), pose=shape.pose)


def _mesh_proposal(model: Model, index: int, rung_from: int, source: str | None, folder: Path) -> Proposal | None:
    shape = model.shapes[index]
    if shape.kind != "mesh" or rung_from >= len(MESH_STEPS):
        return None
    step = MESH_STEPS[rung_from]

    def apply(m: Model) -> Model:
        shapes = list(m.shapes)
        shapes[index] = mesh_as(m.shapes[index], step, source, folder)
        return dataclasses.replace(m, shapes=tuple(shapes))

    return Proposal(f"{model.name}:mesh#{index}", model.name, f"mesh#{index}", Path(str(shape.mesh)).name,
                    f"its {'bounding box' if step == 'box' else 'convex hull'}", apply, rung_from)


def proposals(world: World, rungs: dict[str, int] | None, folder: Path) -> list[Proposal]:
    """The simplifications of this pass: every one (`rungs` None, the first pass), else those named in
    `rungs` one rung finer (attributes without a ladder are not tried again)."""
    found: list[Proposal] = []
    named = scenario_models(world)
    fixed = {start_support(world), *named}
    gaps = nearest_gaps(world)
    for model in world.models:
        if model.keep:
            continue
        candidates: list[Proposal | None] = []
        gap = gaps[model.name]  # no rung coarser than the gap to its nearest neighbour
        low, high = world.bounds(model.name)
        reach = max(float(np.hypot(*(high - low)[:2])) / 2.0, 1e-6)  # how far a turn moves its far end

        if rungs is None:
            if model.mu != 1.0 or model.mu2 != 1.0:
                candidates.append(Proposal(f"{model.name}:friction", model.name, "friction",
                                           f"mu = {_number(model.mu)}" + (f", mu2 = {_number(model.mu2)}"
                                                                           if model.mu2 != model.mu else ""),
                                           "mu = 1", lambda m: dataclasses.replace(m, mu=1.0, mu2=1.0)))
            if model.restitution != 0.0:
                candidates.append(Proposal(f"{model.name}:restitution", model.name, "restitution",
                                           _number(model.restitution), "0",
                                           lambda m: dataclasses.replace(m, restitution=0.0)))
            if model.dynamic:
                if model.name not in named:  # an arm's target must stay movable
                    candidates.append(Proposal(f"{model.name}:static", model.name, "static", "dynamic", "static",
                                               lambda m: dataclasses.replace(m, static=True)))
                if model.mass is not None and model.mass != 1.0:
                    candidates.append(Proposal(f"{model.name}:mass", model.name, "mass",
                                               f"{_number(model.mass)} kg", "1 kg (the default)",
                                               lambda m: dataclasses.replace(m, mass=1.0)))
        moves_start = model.name in fixed  # never move what the robot starts on, nor an arm's table or target
        for key in ("x", "y") if not moves_start else ():
            rung = _rung(rungs, model.name, key)
            if rung is not None:
                candidates.append(_ladder_proposal(model, key, rung, _pose_get(key), _pose_put(key), LENGTHS,
                                                   largest=gap))
        rung = _rung(rungs, model.name, "yaw")
        if rung is not None and not moves_start:
            candidates.append(_ladder_proposal(model, "yaw", rung, _pose_get("yaw"), _pose_put("yaw"), ANGLES,
                                               shown=_degrees, largest=gap / reach))
        for index in range(len(model.shapes)):
            rung = _rung(rungs, model.name, f"size#{index}")
            if rung is not None and not moves_start:
                candidates.append(_size_proposal(model, index, rung, largest=gap))
            rung = _rung(rungs, model.name, f"mesh#{index}")
            if rung is not None:
                candidates.append(_mesh_proposal(model, index, rung, world.source, folder))
        found.extend(proposal for proposal in candidates if proposal is not None)
    return found


def _rung(rungs: dict[str, int] | None, model: str, attribute: str) -> int | None:
    """The ladder rung to try for `attribute` of `model` in this pass (None: not this pass)."""
    if rungs is None:
        return 0
    key = f"{model}:{attribute}"
    return rungs[key] + 1 if key in rungs else None


def simplified(world: World, applied: list[Proposal]) -> World:
    """`world` with the `applied` simplifications (in order, per model)."""
    by_model: dict[str, list[Proposal]] = {}
    for proposal in applied:
        by_model.setdefault(proposal.model, []).append(proposal)

    def changed(model: Model) -> Model:
        for proposal in by_model.get(model.name, ()):
            model = proposal.apply(model)
        return model

    return dataclasses.replace(world, models=tuple(changed(model) for model in world.models))


def run(context: StageContext, folder: Path) -> StageResult:
    world = context.base
    begin = context.budget.started()
    held: list[Proposal] = []
    broke: dict[str, Proposal] = {}
    refused: dict[str, tuple[Proposal, str]] = {}
    undecided: list[Proposal] = []
    rate: list[int] | None = None
    probes = 0
    incomplete: str | None = None
    rungs: dict[str, int] | None = None
    width = None if context.run is None else float(context.run.footprint[1])  # the robot's, for its gaps
    robot = "the arm's hand" if context.run is not None and context.run.robot_kind == "arm" else "the robot"
    for number in range(PASSES):
        offered = proposals(world, rungs, folder)
        if not offered:
            break
        by_name = {proposal.name: proposal for proposal in offered}

        def build(candidate: Candidate, base: World = world, offered: list[Proposal] = offered) -> World:
            kept = set(candidate)
            return simplified(base, [proposal for proposal in offered if proposal.name not in kept])

        reduction = context.reduce_edits(f"{STAGE}-{number + 1}", tuple(by_name), build, stage_begin=begin,
                                         preconditions=(keeps_structure(world, build, width, robot),),
                                         rate_runs=RATE_RUNS)
        if reduction is None:  # what this pass offers is undecided, not "nothing to simplify"
            incomplete = "budget: no probes left"
            undecided = [proposal for proposal in offered if proposal.name not in broke.keys() | refused.keys()]
            break
        probes += reduction.probes
        needed = set(reduction.minimal)
        passed = [proposal for proposal in offered if proposal.name not in needed]
        held.extend(passed)
        for proposal in passed:
            broke.pop(proposal.name, None)
            refused.pop(proposal.name, None)
        world = build(reduction.minimal)
        if reduction.failure_rate[1]:
            rate = list(reduction.failure_rate)
        if not reduction.one_minimal:  # what is left was not shown needed: undecided, not "needed"
            undecided = [by_name[name] for name in reduction.minimal]
            for proposal in undecided:
                broke.pop(proposal.name, None)
                refused.pop(proposal.name, None)
            incomplete = reduction.incomplete_reason
            break
        different = dict(reduction.precondition_kept)  # applying it alone would change the structure
        for name in reduction.minimal:  # in the world's order, not a set's: the findings' order is reproducible
            if name in different:
                refused[name] = (by_name[name], different[name])
                broke.pop(name, None)
            else:
                broke[name] = by_name[name]
                refused.pop(name, None)
        rungs = {name: by_name[name].rung for name in needed}
    findings = [f"{p.model}: {p.attribute} {p.before} -> {p.after} (the failure holds)" for p in held]
    findings += [f"{p.model}: the failure needs {p.attribute} {p.before} (not {p.after})" for p in broke.values()]
    findings += [f"{p.model}: {p.attribute} {p.before} -> {p.after} not applied: it {why}"
                 for p, why in refused.values()]
    findings += [f"{p.model}: {p.attribute} {p.before} -> {p.after} not decided ({incomplete})" for p in undecided]
    details: dict[str, Any] = {"held": [_as_dict(p) for p in held], "broke": [_as_dict(p) for p in broke.values()],
                               "different_structure": [{**_as_dict(p), "why": why} for p, why in refused.values()],
                               "undecided": [_as_dict(p) for p in undecided]}
    if rate is not None:
        details["failure_rate"] = rate
    return StageResult(STAGE, world, probes=probes, simulations=context.budget.started() - begin,
                       findings=findings or ["nothing to simplify"], details=details, incomplete=incomplete,
                       differences={f"{p.model}: {p.attribute} {p.before} -> {p.after}": _applying(p)
                                    for p in broke.values()})


def _applying(proposal: Proposal) -> Callable[[World], World]:
    return lambda world: simplified(world, [proposal])


def _as_dict(proposal: Proposal) -> dict[str, str]:
    return {"model": proposal.model, "attribute": proposal.attribute, "from": proposal.before, "to": proposal.after}

