"""Hypothesis strategies that draw scenario worlds which are physically valid by construction.

`worlds()` draws a `World`: a scenario (the robot's start and goal), the ground, and models resting on the
ground (or on top of one another) inside a region, never overlapping each other, the robot's start or the
goal. `models()`, `poses()` and `scenarios()` are its parts. `tabletop_worlds()` draws an arm's world: a
table, the arm at its edge, a target, a place region and clutter standing on the table top. Every value is
drawn with Hypothesis's `draw`, so examples shrink (toward fewer, smaller, static boxes near the middle of
their places) and replay from `@seed` and the example database. Lengths are drawn in whole millimetres,
headings in whole degrees: the YAML of a drawn world stays readable and round-trips exactly.

Arguments are checked when a strategy is built: a request that cannot be met (more models than the region
holds) raises `hypothesis.errors.InvalidArgument` at once, saying what to change. See
docs/generating-worlds.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from hypothesis import strategies as st

from pytest_ddenv.errors import shown
from pytest_ddenv.strategies._arguments import (
    _checked_count,
    _checked_flag,
    _checked_footprint,
    _checked_number,
    _checked_point,
    _checked_probability,
    _checked_range,
    _checked_region,
    _checked_world_parts,
    _fail,
    _is_region,
    _milli,
)
from pytest_ddenv.strategies._bodies import _checked_templates, _Primitives
from pytest_ddenv.strategies._defaults import (
    DEFAULT_FRICTION,
    DEFAULT_MASS,
    DEFAULT_REGION,
    DEFAULT_SCENARIO,
    DEFAULT_SIZE,
    HUSKY_FOOTPRINT,
    MILLI,
    PRIMITIVE_KINDS,
    STACK_STEPS,
    Point,
    PrimitiveKind,
    Range,
    Region,
)
from pytest_ddenv.strategies._drawing import _Drawn
from pytest_ddenv.strategies._grid import _Grid
from pytest_ddenv.strategies._plans import (
    _call,
    _checked_room,
    _ModelPlan,
    _PosePlan,
    _ScenarioPlan,
    _WorldPlan,
)
from pytest_ddenv.strategies._tabletop import PANDA_BASE_RADIUS, tabletop_worlds
from pytest_ddenv.validation import is_real
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Ground, Model, Physics, Pose, RobotDescription, Scenario, World

__all__ = [
    "DEFAULT_REGION",
    "DEFAULT_SCENARIO",
    "HUSKY_FOOTPRINT",
    "PANDA_BASE_RADIUS",
    "PRIMITIVE_KINDS",
    "models",
    "poses",
    "scenarios",
    "tabletop_worlds",
    "worlds",
]


def poses(region: Region = DEFAULT_REGION, z: float = 0.0, yaw: bool = True) -> st.SearchStrategy[Pose]:
    """Poses with x, y in `region` ((xmin, ymin), (xmax, ymax)) in whole millimetres, at height `z`, heading
    a whole number of degrees in (-180, 180] (0 when `yaw` is False). Shrinks toward the region's centre,
    heading 0."""
    call = _call(poses, locals())
    (xmin, ymin), (xmax, ymax) = _checked_region("poses", region)
    height = _checked_number("poses", "z", z, low=-math.inf)
    turns = _checked_flag("poses", "yaw", yaw)
    plan = _PosePlan(_milli("poses", "region", (xmin, xmax)), _milli("poses", "region", (ymin, ymax)), height, turns,
                     call=call)
    return _Drawn.poses(plan)


def models(
    kinds: Sequence[PrimitiveKind] = PRIMITIVE_KINDS,
    *,
    size: Range = DEFAULT_SIZE,
    mass: Range = DEFAULT_MASS,
    friction: Range = DEFAULT_FRICTION,
    static: bool | None = None,
    yaw: bool = True,
    name: str | None = None,
    pose: Pose | st.SearchStrategy[Pose] | None = None,
    template: Model | None = None,
) -> st.SearchStrategy[Model]:
    """One model resting on the ground: its footprint centred on the origin (or on `pose`'s x, y), its lowest
    point at z = 0 (or `pose.z`), heading `pose.yaw`, turned by a drawn heading when `yaw` is True (boxes and
    templates: a cylinder or sphere looks the same at every heading).

    A primitive of one of `kinds`: a box (its three sides), an upright cylinder (diameter and length) or a
    sphere (diameter), every length drawn in `size` (m); static, dynamic or either (`static` None), with a
    `mass` (kg) when dynamic; friction coefficient mu = mu2 in `friction`. With `template` (a model of yours,
    e.g. from a world file), that model moved there instead (its shapes, mass and friction kept). `name`
    defaults to the kind, or the template's name.
    """
    call = _call(models, locals())
    primitives = _Primitives.checked("models", kinds, size, mass, friction, static, yaw)
    if template is not None and not isinstance(template, Model):
        raise _fail("models", "template", f"expected a Model or None, got {shown(template)}")
    bodies = _checked_templates("models", template, "template")
    if not bodies and not primitives.kinds:
        raise _fail("models", "kinds", "no kinds and no template: nothing to draw")
    problem = None if name is None else name_problem(name)
    if problem is not None:
        raise _fail("models", "name", f"{problem}, got {shown(name)}")
    if pose is not None and not isinstance(pose, (Pose, st.SearchStrategy)):
        raise _fail("models", "pose", f"expected a Pose, a strategy of Poses or None, got {shown(pose)}")
    return _Drawn.models(_ModelPlan(primitives, bodies[0] if bodies else None, name, pose, call=call))


def scenarios(
    robot: str | RobotDescription = "husky",
    *,
    start: Pose | Region | st.SearchStrategy[Pose] = DEFAULT_SCENARIO.start,
    goal: Point | Region | st.SearchStrategy[Point] = DEFAULT_SCENARIO.goal[:2],
    timeout: float | Range = Scenario.timeout,
    goal_tolerance: float = Scenario.goal_tolerance,
) -> st.SearchStrategy[Scenario]:
    """A scenario: `robot` (a registered robot's name or a `RobotDescription`) starts at `start` (a Pose; a
    region ((xmin, ymin), (xmax, ymax)) to draw a pose in, at any heading; or a strategy of Poses) and drives
    to `goal` (a point (x, y), a region to draw it in, or a strategy of points) within `timeout` simulated
    seconds (a number, or a (lo, hi) range drawn in milliseconds); the goal counts as reached within
    `goal_tolerance` m. The defaults are `DEFAULT_SCENARIO`'s."""
    call = _call(scenarios, locals())
    if not (isinstance(robot, RobotDescription) or (isinstance(robot, str) and name_problem(robot) is None)):
        raise _fail("scenarios", "robot", f"expected a robot name or a RobotDescription, got {shown(robot)}")
    starts: st.SearchStrategy[Pose]
    if isinstance(start, Pose):
        starts = st.just(start)
    elif isinstance(start, st.SearchStrategy):
        starts = start
    elif _is_region(start):
        starts = poses(_checked_region("scenarios", start))
    else:
        raise _fail("scenarios", "start", f"expected a Pose, a region or a strategy of Poses, got {shown(start)}")
    goals: st.SearchStrategy[Point]
    if isinstance(goal, st.SearchStrategy):
        goals = goal
    elif _is_region(goal):
        goals = poses(_checked_region("scenarios", goal), yaw=False).map(lambda pose: (pose.x, pose.y))
    else:
        goals = st.just(_checked_point("scenarios", "goal", goal))
    timeouts: st.SearchStrategy[float]
    if is_real(timeout):
        timeouts = st.just(_checked_number("scenarios", "timeout", timeout, low_included=False))
    else:
        lo, hi = _milli("scenarios", "timeout", _checked_range("scenarios", "timeout", timeout))
        timeouts = st.integers(lo, hi).map(lambda n: n / MILLI)
    tolerance = _checked_number("scenarios", "goal_tolerance", goal_tolerance, low_included=False)
    return _Drawn.scenarios(_ScenarioPlan(robot, starts, goals, timeouts, tolerance, call=call))


def worlds(
    scenario: Scenario | st.SearchStrategy[Scenario] | None = DEFAULT_SCENARIO,
    *,
    count: int | tuple[int, int] = (0, 10),
    region: Region = DEFAULT_REGION,
    clearance: float = 0.3,
    kinds: Sequence[PrimitiveKind] = PRIMITIVE_KINDS,
    templates: Sequence[Model] | World | None = None,
    size: Range = DEFAULT_SIZE,
    mass: Range = DEFAULT_MASS,
    friction: Range = DEFAULT_FRICTION,
    static: bool | None = None,
    yaw: bool = True,
    overlap: bool = False,
    stacked: float = 0.0,
    robot_footprint: tuple[float, float] | None = None,
    ground: Ground | None = Ground(),
    physics: Physics = Physics(),
    name: str = "generated",
) -> st.SearchStrategy[World]:
    """Worlds of `count` models (a number, or a (lo, hi) range) inside `region`, with `scenario` (a Scenario,
    a strategy of them such as `scenarios()`, or None: no scenario), the `ground` plane and `physics`.

    Each model is a primitive drawn as by `models(kinds, size=, mass=, friction=, static=, yaw=)`, or one of
    `templates` (models of yours, or a World's models) moved to a drawn place; names are "box_0",
    "cylinder_1", "<template>_2", ... Models rest on the ground, their footprints (axis-aligned bounds)
    inside the region and at least `clearance` m apart, unless `overlap` is True (then several may share a
    place); never within `clearance` of the robot's footprint at its start, at the start heading, nor of the
    robot standing on the goal, at any heading (`robot_footprint` (length, width) in m, by default the
    Husky's). With probability `stacked`, a model rests instead on top of an earlier box or cylinder, inside
    its top face (a small model: at most as wide as that face; one model on each, no towers).

    Raises InvalidArgument at once when the region cannot hold `count` models.
    """
    call = _call(worlds, locals())
    primitives = _Primitives.checked("worlds", kinds, size, mass, friction, static, yaw)
    bodies = _checked_templates("worlds", templates)
    if not primitives.kinds and not bodies:
        raise _fail("worlds", "kinds", "no kinds and no templates: nothing to draw")
    counts = _checked_count(count)
    area = _checked_region("worlds", region)
    gap = _checked_number("worlds", "clearance", clearance)
    overlaps = _checked_flag("worlds", "overlap", overlap)
    chance = _checked_probability("worlds", "stacked", stacked)
    footprint = None if robot_footprint is None else _checked_footprint(robot_footprint)
    _checked_world_parts(scenario, ground, physics, name)

    widest = max([primitives.widest(), *(b.widest(yaw) for b in bodies)])
    plan = _WorldPlan(scenario=scenario, count=counts, grid=_Grid.of(area, widest, gap), free=None,
                      primitives=primitives, templates=bodies, clearance=gap, overlap=overlaps,
                      stacked=round(chance * STACK_STEPS), footprint=footprint, ground=ground, physics=physics,
                      name=name, call=call)
    return _Drawn.worlds(_checked_room(plan, area, widest))
