"""The plans: each strategy's checked arguments, shown in Hypothesis's messages as the call the user wrote."""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from pytest_ddenv.errors import shown
from pytest_ddenv.strategies._bodies import _Body, _Primitives
from pytest_ddenv.strategies._defaults import HUSKY_FOOTPRINT, Point, Region
from pytest_ddenv.strategies._grid import _Grid, _keep_out, _too_many
from pytest_ddenv.world.model import Ground, Physics, Pose, RobotDescription, Scenario


def _call(function: Callable[..., object], values: Mapping[str, object]) -> str:
    """The arguments of a call of `function` that differ from its defaults, as `name=value` (clipped)."""
    shown_arguments = []
    for name, parameter in inspect.signature(function).parameters.items():
        value = values[name]
        if value is parameter.default:
            continue
        try:
            same = bool(value == parameter.default)
        except Exception:  # noqa: BLE001 - a value that cannot be compared counts as given
            same = False
        if not same:
            shown_arguments.append(f"{name}={shown(value)}")
    return ", ".join(shown_arguments)


@dataclass(frozen=True)
class _Plan:
    """Checked arguments of a strategy; shown as the arguments the user gave (see `_Drawn`)."""

    call: str = field(compare=False, kw_only=True)

    def __repr__(self) -> str:
        return self.call

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """Hypothesis's pretty printer (IPython's protocol): the call too, not the dataclass's fields."""
        printer.text(self.call)


@dataclass(frozen=True, repr=False)
class _PosePlan(_Plan):
    x: tuple[int, int]
    y: tuple[int, int]
    z: float
    yaw: bool


@dataclass(frozen=True, repr=False)
class _ModelPlan(_Plan):
    primitives: _Primitives
    template: _Body | None
    name: str | None
    pose: Pose | st.SearchStrategy[Pose] | None


@dataclass(frozen=True, repr=False)
class _ScenarioPlan(_Plan):
    robot: str | RobotDescription
    start: st.SearchStrategy[Pose]
    goal: st.SearchStrategy[Point]
    timeout: st.SearchStrategy[float]
    goal_tolerance: float


@dataclass(frozen=True, repr=False)
class _WorldPlan(_Plan):
    """Everything `worlds()` checked, ready to draw from."""

    scenario: Scenario | st.SearchStrategy[Scenario] | None
    count: tuple[int, int]
    grid: _Grid
    free: tuple[tuple[int, int], ...] | None
    """The cells a fixed scenario leaves free (None: found for each drawn scenario)."""
    primitives: _Primitives
    templates: tuple[_Body, ...]
    clearance: float
    overlap: bool
    stacked: int
    """Out of STACK_STEPS."""
    footprint: tuple[float, float] | None
    ground: Ground | None
    physics: Physics
    name: str

    def robot_footprint(self, scenario: Scenario) -> tuple[float, float]:
        if self.footprint is not None:
            return self.footprint
        if scenario.robot != "husky":
            robot = scenario.robot if isinstance(scenario.robot, str) else scenario.robot.label
            raise InvalidArgument(f"worlds(): the scenario's robot is {robot!r}, whose footprint the world model "
                                  "does not know: pass robot_footprint=(length, width) in m")
        return HUSKY_FOOTPRINT


def _checked_room(plan: _WorldPlan, region: Region, widest: float) -> _WorldPlan:
    """The plan, with the cells a fixed scenario leaves free; InvalidArgument when `region` cannot hold the
    most models `count` allows (one when they may overlap) beside the robot's start and goal."""
    grid, gap, counts = plan.grid, plan.clearance, plan.count
    if isinstance(plan.scenario, Scenario):
        free = grid.free(_keep_out(plan.scenario, plan.robot_footprint(plan.scenario), gap))
        plan = dataclasses.replace(plan, free=free)
        blocked, why = len(grid.centres) - len(free), "the robot's start and the goal keep"
    elif plan.scenario is None:
        blocked, why = 0, ""
    else:
        length, width = plan.footprint or HUSKY_FOOTPRINT
        blocked = min(len(grid.centres), 2 * grid.most_blocked(math.hypot(length, width) + 2 * gap))
        why = "a drawn scenario's start and goal may keep"
    needed = min(counts[1], 1) if plan.overlap else counts[1]
    if needed > len(grid.centres) - blocked:
        raise InvalidArgument(_too_many(counts[1], needed, region, grid, widest, blocked, why))
    return plan
