"""The composite strategies: draw a plan's values in a fixed order, then place a world's models from them."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from pytest_ddenv.strategies._bodies import (
    ACROSS,
    SIZES,
    _draw_physics,
    _draw_sizes,
    _name,
    _Physics,
    _primitive,
    _Primitives,
)
from pytest_ddenv.strategies._defaults import MILLI, STACK_STEPS, PrimitiveKind
from pytest_ddenv.strategies._grid import _keep_out
from pytest_ddenv.strategies._plans import _ModelPlan, _PosePlan, _ScenarioPlan, _WorldPlan
from pytest_ddenv.world.model import Model, Pose, Scenario, World


def _draw_milli(draw: st.DrawFn, lo: int, hi: int, towards: int | None = None) -> int:
    """A whole number of thousandths in [lo, hi] that shrinks toward `towards` (default: lo)."""
    if towards is None or lo == hi:
        return draw(st.integers(lo, hi))
    towards = min(max(towards, lo), hi)
    return towards + draw(st.integers(lo - towards, hi - towards))


def _draw_yaw(draw: st.DrawFn) -> float:
    return math.radians(draw(st.integers(-179, 180)))


@dataclass(frozen=True)
class _Draft:
    """What is drawn for one model of a world, before it is placed (see `_Drawn.worlds`): every field is
    drawn whether it is used or not, so that deleting one model's draft leaves the others' as they were."""

    stack: bool
    """Rest on an earlier model (if one can carry it), not on the ground."""
    choice: int
    """Index into the primitive kinds, then the templates."""
    sizes: tuple[int, ...]
    heading: float
    cell: int
    """Index of the wanted cell; the first free one from there is taken."""
    offset: tuple[int, int]
    """Where in its place, in thousandths of the room there, from -1000 to 1000 (0: the middle)."""
    base: int
    """Which of the earlier models that can carry it (modulo their number)."""
    physics: _Physics


@st.composite
def _drafts(draw: st.DrawFn, plan: _WorldPlan) -> _Draft:
    """Every draft draws the same values in the same order (the sizes of a box, a heading, ...) whatever it
    becomes, so that changing one value (a kind, stacked or not) leaves the meaning of the others."""
    spec = plan.primitives
    stack = bool(plan.stacked) and draw(st.integers(0, STACK_STEPS - 1)) >= STACK_STEPS - plan.stacked
    base = draw(st.integers(0, plan.count[1])) if plan.stacked else 0
    choices = len(spec.kinds) + len(plan.templates)
    choice = draw(st.integers(0, choices - 1)) if choices > 1 else 0
    sizes = _draw_sizes(draw, spec, "box") if spec.kinds else ()
    heading = _draw_yaw(draw) if spec.yaw else 0.0
    cell = draw(st.integers(0, len(plan.grid.centres) - 1))
    offset = (draw(st.integers(-MILLI, MILLI)), draw(st.integers(-MILLI, MILLI)))
    physics = _draw_physics(draw, spec) if spec.kinds else _Physics(False, None, 1.0)
    if choice < len(spec.kinds):
        kind = spec.kinds[choice]
        sizes, heading = sizes[:SIZES[kind]], heading if kind == "box" else 0.0
    return _Draft(stack, choice, sizes, heading, cell, offset, base, physics)


@dataclass
class _Resting:
    """A model placed so far, and what can rest on it."""

    model: Model
    top: float
    """Radius of the free disc on its flat top (0: nothing can rest on it)."""
    height: float


def _across(top: float, kind: PrimitiveKind) -> int:
    """The widest side (box) or diameter (cylinder, sphere), in thousandths, of a primitive that fits a disc
    of radius `top` at any heading."""
    return math.floor(2.0 * top * MILLI / (math.sqrt(2.0) if kind == "box" else 1.0))


def _carries(spec: _Primitives, top: float) -> bool:
    """Whether a flat top with a free disc of radius `top` can carry the smallest model of every kind."""
    return top > 0.0 and all(_across(top, kind) >= spec.size[0] for kind in spec.kinds)


def _within(centre: int, room: float, fraction: int) -> float:
    """`fraction` thousandths of the way from `centre` (mm) to `room` (m) either side, in whole mm, as m."""
    reach = max(0, math.floor(room * MILLI))
    return (centre + round(reach * fraction / MILLI)) / MILLI


class _Drawn:
    """The composite strategies, named as the public functions, so that Hypothesis shows
    `worlds(count=(3, 12))` in its messages."""

    @staticmethod
    @st.composite
    def poses(draw: st.DrawFn, plan: _PosePlan) -> Pose:
        x = _draw_milli(draw, *plan.x, towards=sum(plan.x) // 2) / MILLI
        y = _draw_milli(draw, *plan.y, towards=sum(plan.y) // 2) / MILLI
        return Pose(x, y, plan.z, 0.0, 0.0, _draw_yaw(draw) if plan.yaw else 0.0)

    @staticmethod
    @st.composite
    def models(draw: st.DrawFn, plan: _ModelPlan) -> Model:
        spec = plan.primitives
        if plan.template is not None:
            body = plan.template
        else:
            kind = spec.kinds[draw(st.integers(0, len(spec.kinds) - 1))] if len(spec.kinds) > 1 else spec.kinds[0]
            body = _draw_physics(draw, spec).of(_primitive(kind, _draw_sizes(draw, spec, kind)))
        at = plan.pose if isinstance(plan.pose, Pose) else Pose() if plan.pose is None else draw(plan.pose)
        turns = spec.yaw and (plan.template is not None or body.model.shapes[0].kind == "box")
        heading = at.yaw + (_draw_yaw(draw) if turns else 0.0)
        return body.placed(plan.name or body.model.name, at.x, at.y, at.z, heading)

    @staticmethod
    @st.composite
    def scenarios(draw: st.DrawFn, plan: _ScenarioPlan) -> Scenario:
        start = draw(plan.start)
        x, y = draw(plan.goal)
        return Scenario(robot=plan.robot, start=start, goal=(x, y, None), goal_tolerance=plan.goal_tolerance,
                        timeout=draw(plan.timeout))

    @staticmethod
    @st.composite
    def worlds(draw: st.DrawFn, plan: _WorldPlan) -> World:
        """A list of drafts (so that Hypothesis shrinks a world by deleting any of its models), then the
        scenario (drawn first, its many values would make Hypothesis draw empty lists more often), then the
        drafts placed in order: on the first free cell from the one drawn, or on an earlier model."""
        drafts = draw(st.lists(_drafts(plan), min_size=plan.count[0], max_size=plan.count[1]))
        scenario = draw(plan.scenario) if isinstance(plan.scenario, st.SearchStrategy) else plan.scenario
        if plan.free is not None or scenario is None:
            free = plan.free if plan.free is not None else plan.grid.centres
        else:
            free = plan.grid.free(_keep_out(scenario, plan.robot_footprint(scenario), plan.clearance))
        if len(drafts) > len(free) and not (plan.overlap and free):
            raise InvalidArgument(f"worlds({plan.call}): the drawn scenario {scenario} leaves {len(free)} free "
                                  f"cell(s) in the region, fewer than the {len(drafts)} models drawn; pass "
                                  "robot_footprint=, a larger region or fewer models")
        return _World(plan, scenario, frozenset(free)).placed(drafts)


class _World:
    """Places the drafts of one world, in order."""

    def __init__(self, plan: _WorldPlan, scenario: Scenario | None, free: frozenset[tuple[int, int]]) -> None:
        self.plan, self.scenario, self.free = plan, scenario, set(free)
        self.ground_z = plan.ground.z if plan.ground is not None else 0.0
        self.placed_models: list[_Resting] = []

    def placed(self, drafts: Sequence[_Draft]) -> World:
        for index, draft in enumerate(drafts):
            resting = self.stacked(index, draft) if draft.stack else None
            self.placed_models.append(resting or self.on_the_ground(index, draft))
        plan = self.plan
        return World(models=tuple(r.model for r in self.placed_models), scenario=self.scenario,
                     physics=plan.physics, ground=plan.ground, name=plan.name)

    def on_the_ground(self, index: int, draft: _Draft) -> _Resting:
        plan, spec = self.plan, self.plan.primitives
        if draft.choice < len(spec.kinds):
            body = draft.physics.of(_primitive(spec.kinds[draft.choice], draft.sizes))
        else:
            body = plan.templates[draft.choice - len(spec.kinds)]
        cells = plan.grid.centres
        wanted = (cells[(draft.cell + step) % len(cells)] for step in range(len(cells)))
        cell = next(cell for cell in wanted if cell in self.free)
        if not plan.overlap:
            self.free.discard(cell)
        hx, hy = body.half_at(draft.heading)
        x = _within(cell[0], plan.grid.inner - hx, draft.offset[0])
        y = _within(cell[1], plan.grid.inner - hy, draft.offset[1])
        model = body.placed(_name(body.model.name, index), x, y, self.ground_z, draft.heading)
        return _Resting(model, body.top, body.height)

    def stacked(self, index: int, draft: _Draft) -> _Resting | None:
        """The draft resting on an earlier box or cylinder, inside the free disc of its top, made small enough
        (that model then carries nothing more); None when it is a template or nothing can carry it."""
        spec = self.plan.primitives
        below = [r for r in self.placed_models if _carries(spec, r.top)]
        if draft.choice >= len(spec.kinds) or not below:
            return None
        base = below[draft.base % len(below)]
        kind = spec.kinds[draft.choice]
        sizes = [min(size, _across(base.top, kind)) if axis < ACROSS[kind] else size
                 for axis, size in enumerate(draft.sizes)]
        body = draft.physics.of(_primitive(kind, sizes))
        radius = math.hypot(*body.half) if kind == "box" else body.half[0]
        room = (base.top - radius) / math.sqrt(2.0)
        x, y = round(base.model.pose.x * MILLI), round(base.model.pose.y * MILLI)
        model = body.placed(_name(body.model.name, index), _within(x, room, draft.offset[0]),
                            _within(y, room, draft.offset[1]), base.model.pose.z + base.height / 2.0,
                            draft.heading)
        self.placed_models[self.placed_models.index(base)] = dataclasses.replace(base, top=0.0)
        return _Resting(model, 0.0, body.height)
