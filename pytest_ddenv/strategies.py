"""Hypothesis strategies that draw scenario worlds which are physically valid by construction.

`worlds()` draws a `World`: a scenario (the robot's start and goal), the ground, and models resting on the
ground (or on top of one another) inside a region, never overlapping each other, the robot's start or the
goal. `models()`, `poses()` and `scenarios()` are its parts. Every value is drawn with Hypothesis's
`draw`, so examples shrink (toward fewer, smaller, static boxes near the middle of their places) and
replay from `@seed` and the example database. Lengths are drawn in whole millimetres, headings in whole
degrees: the YAML of a drawn world stays readable and round-trips exactly.

Arguments are checked when a strategy is built: a request that cannot be met (more models than the region
holds) raises `hypothesis.errors.InvalidArgument` at once, saying what to change. See
docs/generating-worlds.md.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, TypeAlias

try:
    from hypothesis import strategies as st
    from hypothesis.errors import InvalidArgument
except ImportError as error:  # pragma: no cover - hypothesis is a dev dependency
    raise ImportError("pytest_ddenv.strategies needs Hypothesis: pip install hypothesis") from error

from pytest_ddenv.errors import shown
from pytest_ddenv.validation import is_flag, is_integer, is_real
from pytest_ddenv.world import (
    MAX_NAME_LENGTH,
    Ground,
    Model,
    Physics,
    Pose,
    RobotDescription,
    Scenario,
    Shape,
    World,
    name_problem,
    resolve_relative,
)

__all__ = [
    "DEFAULT_REGION",
    "DEFAULT_SCENARIO",
    "HUSKY_FOOTPRINT",
    "PRIMITIVE_KINDS",
    "models",
    "poses",
    "scenarios",
    "worlds",
]

Point: TypeAlias = tuple[float, float]
Region: TypeAlias = tuple[Point, Point]
"""((xmin, ymin), (xmax, ymax)) in metres, world frame."""
Range: TypeAlias = tuple[float, float]
"""(lowest, highest), both included."""
PrimitiveKind: TypeAlias = Literal["box", "cylinder", "sphere"]

PRIMITIVE_KINDS: tuple[PrimitiveKind, ...] = ("box", "cylinder", "sphere")
HUSKY_FOOTPRINT: tuple[float, float] = (0.99, 0.67)
"""The built-in Husky's (length, width) in metres: `pytest_ddenv.sim.Husky().footprint`, which this layer
cannot import (tests/test_strategies.py checks that they agree)."""
DEFAULT_REGION: Region = ((0.0, -5.0), (10.0, 5.0))
DEFAULT_SCENARIO = Scenario(start=Pose(0.0, 0.0, 0.0), goal=(10.0, 0.0, None))
"""The robot starts at the origin heading +x; the goal is 10 m ahead (the far edge of DEFAULT_REGION)."""
DEFAULT_SIZE: Range = (0.2, 0.8)
DEFAULT_MASS: Range = (0.5, 10.0)
DEFAULT_FRICTION: Range = (0.5, 1.0)
MILLI = 1000
"""Lengths, masses and friction coefficients are drawn in steps of 1 / MILLI (millimetres, grams)."""
STACK_STEPS = 100
"""`stacked` is honoured to 1 / STACK_STEPS."""


# -- argument checks (eager, hypothesis style) ---------------------------------------------------------------
def _fail(function: str, argument: str, message: str) -> InvalidArgument:
    return InvalidArgument(f"{function}({argument}=...): {message}")


def _checked_range(function: str, argument: str, value: object, *, low: float = 0.0,
                   low_included: bool = False) -> Range:
    """A (lo, hi) pair of finite numbers with low (<)= lo <= hi; InvalidArgument otherwise."""
    bound = f">= {low:g}" if low_included else f"> {low:g}"
    if not (isinstance(value, (tuple, list)) and len(value) == 2 and all(is_real(v) for v in value)):
        raise _fail(function, argument, f"expected a pair (lowest, highest) of numbers {bound}, got {value!r}")
    lo, hi = float(value[0]), float(value[1])
    if not (math.isfinite(lo) and math.isfinite(hi)) or not (lo >= low if low_included else lo > low):
        raise _fail(function, argument, f"expected finite numbers {bound}, got {value!r}")
    if lo > hi:
        raise _fail(function, argument, f"the lowest value {lo:g} is above the highest {hi:g}")
    return lo, hi


def _checked_region(function: str, value: object) -> Region:
    corners = value if isinstance(value, (tuple, list)) and len(value) == 2 else ()
    numbers: list[object] = [v for corner in corners if isinstance(corner, (tuple, list)) and len(corner) == 2
                             for v in corner]
    if len(numbers) != 4:
        raise _fail(function, "region", f"expected ((xmin, ymin), (xmax, ymax)), got {value!r}")
    if not all(is_real(v) and math.isfinite(v) for v in numbers):
        raise _fail(function, "region", f"expected four finite numbers, got {value!r}")
    xmin, ymin, xmax, ymax = (float(v) for v in numbers)  # type: ignore[arg-type]
    if not (xmin < xmax and ymin < ymax):
        raise _fail(function, "region", f"expected xmin < xmax and ymin < ymax, got {value!r}")
    return (xmin, ymin), (xmax, ymax)


def _checked_point(function: str, argument: str, value: object) -> Point:
    if not (isinstance(value, (tuple, list)) and len(value) == 2
            and all(is_real(v) and math.isfinite(v) for v in value)):
        raise _fail(function, argument, f"expected a point (x, y) of finite numbers, got {value!r}")
    return float(value[0]), float(value[1])


def _is_region(value: object) -> bool:
    return isinstance(value, (tuple, list)) and len(value) == 2 and all(
        isinstance(corner, (tuple, list)) for corner in value)


def _checked_kinds(function: str, kinds: object) -> tuple[PrimitiveKind, ...]:
    if isinstance(kinds, str) or not isinstance(kinds, (tuple, list)):
        raise _fail(function, "kinds", f"expected a sequence of {', '.join(PRIMITIVE_KINDS)}, got {kinds!r}")
    unknown = [kind for kind in kinds if kind not in PRIMITIVE_KINDS]
    if unknown:
        raise _fail(function, "kinds", f"unknown kind(s) {unknown!r}; drawn primitives are {PRIMITIVE_KINDS} "
                                       "(other shapes: pass models of your own as templates)")
    return tuple(dict.fromkeys(kinds))


def _checked_static(function: str, static: object) -> bool | None:
    if static is not None and not is_flag(static):
        raise _fail(function, "static", f"expected True, False or None (both), got {static!r}")
    return static


def _checked_number(function: str, argument: str, value: object, *, low: float = 0.0,
                    low_included: bool = True) -> float:
    if not (is_real(value) and math.isfinite(value) and (value >= low if low_included else value > low)):
        bound = f">= {low:g}" if low_included else f"> {low:g}"
        raise _fail(function, argument, f"expected a finite number {bound}, got {value!r}")
    return float(value)


def _milli(function: str, argument: str, bounds: Range) -> tuple[int, int]:
    """The range in thousandths, rounded inward; InvalidArgument when it holds no whole thousandth."""
    lo, hi = math.ceil(round(bounds[0] * MILLI, 6)), math.floor(round(bounds[1] * MILLI, 6))
    if lo > hi:
        raise _fail(function, argument, f"{bounds!r} holds no multiple of {1 / MILLI:g} (values are drawn in "
                                        "thousandths); widen it")
    return lo, hi


# -- the pieces of a model -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Primitives:
    """How primitive models are drawn (checked arguments, lengths and masses in thousandths)."""

    kinds: tuple[PrimitiveKind, ...]
    size: tuple[int, int]
    mass: tuple[int, int]
    friction: tuple[int, int]
    static: bool | None
    yaw: bool

    @classmethod
    def checked(cls, function: str, kinds: object, size: object, mass: object, friction: object, static: object,
                yaw: object) -> _Primitives:
        if not is_flag(yaw):
            raise _fail(function, "yaw", f"expected True or False, got {yaw!r}")
        return cls(
            kinds=_checked_kinds(function, kinds),
            size=_milli(function, "size", _checked_range(function, "size", size)),
            mass=_milli(function, "mass", _checked_range(function, "mass", mass)),
            friction=_milli(function, "friction", _checked_range(function, "friction", friction,
                                                                 low_included=True)),
            static=_checked_static(function, static),
            yaw=yaw,
        )

    def widest(self) -> float:
        """The widest footprint (m, along x or y) a drawn primitive can have."""
        if not self.kinds:
            return 0.0
        largest = self.size[1] / MILLI
        return largest * math.sqrt(2.0) if "box" in self.kinds and self.yaw else largest


@dataclass(frozen=True)
class _Body:
    """A model at the origin: its footprint centred on (0, 0), its lowest point at z = 0, heading 0.

    `half` is its footprint's half extents (x, y) at heading 0; `top` the radius of the largest disc on its
    flat top (0 when it has none: a sphere or a template); `height` its height.
    """

    model: Model
    half: tuple[float, float]
    height: float
    top: float = 0.0

    def widest(self, turns: bool) -> float:
        """The widest its footprint gets along x or y (m): at any heading when it `turns`."""
        return 2.0 * (math.hypot(*self.half) if turns else max(self.half))

    def half_at(self, yaw: float) -> tuple[float, float]:
        """Half extents of the footprint's axis-aligned bounds at heading `yaw` (exact for boxes, and for
        any body an outer bound: the bounds of its turned bounds)."""
        c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
        hx, hy = self.half
        return hx * c + hy * s, hx * s + hy * c

    def placed(self, name: str, x: float, y: float, z: float, yaw: float) -> Model:
        """The model named `name` turned by `yaw`, its footprint centred on (x, y), its lowest point at z."""
        pose = self.model.pose
        if pose.roll == 0.0 and pose.pitch == 0.0 and pose.x == 0.0 and pose.y == 0.0:
            moved = Pose(x, y, round(z + pose.z, 9), 0.0, 0.0, pose.yaw + yaw)  # 0.3, not 0.30000000000000004
        else:
            moved = Pose(x, y, z, 0.0, 0.0, yaw).compose(pose)
        return dataclasses.replace(self.model, name=name, pose=moved)


def _template_body(template: Model, source: str | None) -> _Body:
    """A user's model as a body: centred on its footprint, resting on z = 0 (mesh paths made absolute)."""
    shapes = tuple(
        dataclasses.replace(shape, mesh=str(resolve_relative(shape.mesh, source).resolve()))
        if shape.mesh is not None and source is not None else shape
        for shape in template.shapes
    )
    model = dataclasses.replace(template, shapes=shapes)
    low, high = (tuple(float(v) for v in corner) for corner in World(models=(model,)).bounds(model.name))
    centre_x, centre_y = (low[0] + high[0]) / 2.0, (low[1] + high[1]) / 2.0
    pose = template.pose
    model = dataclasses.replace(model, pose=Pose(pose.x - centre_x, pose.y - centre_y, pose.z - low[2],
                                                 pose.roll, pose.pitch, pose.yaw))
    return _Body(model, half=((high[0] - low[0]) / 2.0, (high[1] - low[1]) / 2.0), height=high[2] - low[2])


def _checked_templates(function: str, templates: object, argument: str = "templates") -> tuple[_Body, ...]:
    """The templates (Models, or a World's models with their mesh paths made absolute) as bodies."""
    if templates is None:
        return ()
    source = None
    if isinstance(templates, World):
        source, templates = templates.source, templates.models
    if isinstance(templates, Model):
        templates = (templates,)
    if not isinstance(templates, (tuple, list)) or not all(isinstance(t, Model) for t in templates):
        raise _fail(function, argument, f"expected a World or a sequence of Models, got {shown(templates)}")
    bodies = []
    for template in templates:
        problem = name_problem(template.name)
        if problem is not None:
            raise _fail(function, argument, f"model {shown(template.name)}: {problem}")
        bodies.append(_template_body(template, source))
    return tuple(bodies)


def _draw_milli(draw: st.DrawFn, lo: int, hi: int, towards: int | None = None) -> int:
    """A whole number of thousandths in [lo, hi] that shrinks toward `towards` (default: lo)."""
    if towards is None or lo == hi:
        return draw(st.integers(lo, hi))
    towards = min(max(towards, lo), hi)
    return towards + draw(st.integers(lo - towards, hi - towards))


def _primitive(kind: PrimitiveKind, sizes: Sequence[int]) -> _Body:
    """A primitive body from its sizes in millimetres: box (x, y, z), cylinder (diameter, length), sphere
    (diameter)."""
    if kind == "box":
        sx, sy, sz = (size / MILLI for size in sizes)
        model = Model(kind, (Shape("box", size=(sx, sy, sz)),), pose=Pose(0.0, 0.0, sz / 2.0))
        return _Body(model, half=(sx / 2.0, sy / 2.0), height=sz, top=min(sx, sy) / 2.0)
    diameter = sizes[0] / MILLI
    if kind == "cylinder":
        length = sizes[1] / MILLI
        model = Model(kind, (Shape("cylinder", radius=diameter / 2.0, length=length),),
                      pose=Pose(0.0, 0.0, length / 2.0))
        return _Body(model, half=(diameter / 2.0, diameter / 2.0), height=length, top=diameter / 2.0)
    model = Model(kind, (Shape("sphere", radius=diameter / 2.0),), pose=Pose(0.0, 0.0, diameter / 2.0))
    return _Body(model, half=(diameter / 2.0, diameter / 2.0), height=diameter)


SIZES = {"box": 3, "cylinder": 2, "sphere": 1}
"""How many sizes each primitive kind has."""
ACROSS = {"box": 2, "cylinder": 1, "sphere": 1}
"""How many of them are across its footprint (the first ones)."""


def _draw_sizes(draw: st.DrawFn, spec: _Primitives, kind: PrimitiveKind) -> tuple[int, ...]:
    return tuple(draw(st.integers(*spec.size)) for _ in range(SIZES[kind]))


@dataclass(frozen=True)
class _Physics:
    """Static, or dynamic with a mass (kg); the friction coefficient (mu = mu2)."""

    dynamic: bool
    mass: float | None
    mu: float

    def of(self, body: _Body) -> _Body:
        model = dataclasses.replace(body.model, static=not self.dynamic, mass=self.mass, mu=self.mu, mu2=self.mu)
        return dataclasses.replace(body, model=model)


def _draw_physics(draw: st.DrawFn, spec: _Primitives) -> _Physics:
    """Static or dynamic (shrinks to static), a mass when dynamic, a friction coefficient. The mass is drawn
    even for a static model unless all are static, so that turning one dynamic moves no other value."""
    dynamic = (not spec.static) if spec.static is not None else draw(st.booleans())
    mass = draw(st.integers(*spec.mass)) / MILLI if spec.static is not True else None
    return _Physics(dynamic, mass if dynamic else None, draw(st.integers(*spec.friction)) / MILLI)


def _draw_yaw(draw: st.DrawFn) -> float:
    return math.radians(draw(st.integers(-179, 180)))


# -- what a strategy shows in Hypothesis's messages ------------------------------------------------------------
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


# -- public strategies ----------------------------------------------------------------------------------------
def poses(region: Region = DEFAULT_REGION, z: float = 0.0, yaw: bool = True) -> st.SearchStrategy[Pose]:
    """Poses with x, y in `region` ((xmin, ymin), (xmax, ymax)) in whole millimetres, at height `z`, heading
    a whole number of degrees in (-180, 180] (0 when `yaw` is False). Shrinks toward the region's centre,
    heading 0."""
    call = _call(poses, locals())
    (xmin, ymin), (xmax, ymax) = _checked_region("poses", region)
    height = _checked_number("poses", "z", z, low=-math.inf)
    if not is_flag(yaw):
        raise _fail("poses", "yaw", f"expected True or False, got {yaw!r}")
    plan = _PosePlan(_milli("poses", "region", (xmin, xmax)), _milli("poses", "region", (ymin, ymax)), height, yaw,
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
    robot: str | RobotDescription = Scenario.robot,
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
    if not is_flag(overlap):
        raise _fail("worlds", "overlap", f"expected True or False, got {overlap!r}")
    chance = _checked_number("worlds", "stacked", stacked)
    if chance > 1.0:
        raise _fail("worlds", "stacked", f"expected a probability from 0 to 1, got {stacked!r}")
    footprint = None if robot_footprint is None else _checked_footprint(robot_footprint)
    if ground is not None and not isinstance(ground, Ground):
        raise _fail("worlds", "ground", f"expected a Ground or None, got {shown(ground)}")
    if not isinstance(physics, Physics):
        raise _fail("worlds", "physics", f"expected a Physics, got {shown(physics)}")
    if name_problem(name) is not None:
        raise _fail("worlds", "name", f"{name_problem(name)}, got {shown(name)}")
    if scenario is not None and not isinstance(scenario, (Scenario, st.SearchStrategy)):
        raise _fail("worlds", "scenario", f"expected a Scenario, a strategy of Scenarios or None, got "
                                          f"{shown(scenario)}")

    widest = max([primitives.widest(), *(b.widest(yaw) for b in bodies)])
    grid = _Grid.of(area, widest, gap)
    plan = _WorldPlan(scenario=scenario, count=counts, grid=grid, free=None, primitives=primitives,
                      templates=bodies, clearance=gap, overlap=overlap, stacked=round(chance * STACK_STEPS),
                      footprint=footprint, ground=ground, physics=physics, name=name, call=call)
    if isinstance(scenario, Scenario):
        free = grid.free(_keep_out(scenario, plan.robot_footprint(scenario), gap))
        plan = dataclasses.replace(plan, free=free)
        blocked, why = len(grid.centres) - len(free), "the robot's start and the goal keep"
    elif scenario is None:
        blocked, why = 0, ""
    else:
        length, width = footprint or HUSKY_FOOTPRINT
        blocked = min(len(grid.centres), 2 * grid.most_blocked(math.hypot(length, width) + 2 * gap))
        why = "a drawn scenario's start and goal may keep"
    needed = min(counts[1], 1) if overlap else counts[1]
    if needed > len(grid.centres) - blocked:
        raise InvalidArgument(_too_many(counts[1], needed, area, grid, widest, blocked, why))
    return _Drawn.worlds(plan)


def _checked_count(count: object) -> tuple[int, int]:
    if is_integer(count):
        counts = (count, count)
    elif isinstance(count, (tuple, list)) and len(count) == 2 and all(is_integer(c) for c in count):
        counts = (count[0], count[1])
    else:
        raise _fail("worlds", "count", f"expected a whole number or a pair (lowest, highest), got {shown(count)}")
    if counts[0] < 0 or counts[0] > counts[1]:
        raise _fail("worlds", "count", f"expected 0 <= lowest <= highest, got {count!r}")
    return counts


def _checked_footprint(footprint: object) -> tuple[float, float]:
    if not (isinstance(footprint, (tuple, list)) and len(footprint) == 2
            and all(is_real(v) and math.isfinite(v) and v > 0 for v in footprint)):
        raise _fail("worlds", "robot_footprint", f"expected (length, width) in m, two numbers > 0, got "
                                                 f"{shown(footprint)}")
    return float(footprint[0]), float(footprint[1])


# -- worlds: the grid of places ------------------------------------------------------------------------------
Rectangle: TypeAlias = tuple[float, float, float, float]
"""(xmin, ymin, xmax, ymax) in metres."""


@dataclass(frozen=True)
class _Grid:
    """The region cut into square cells of `pitch` m (a whole, even number of millimetres, so that cell
    centres are whole millimetres): each model resting on the ground gets a cell of its own and stays
    `clearance` / 2 inside it, so that models in two cells are at least `clearance` apart."""

    centres: tuple[tuple[int, int], ...]
    """Cell centres in millimetres, row by row from (xmin, ymin)."""
    columns: int
    rows: int
    pitch: float
    clearance: float

    @classmethod
    def of(cls, region: Region, widest: float, clearance: float) -> _Grid:
        pitch_mm = 2 * math.ceil(round((widest + clearance) * MILLI, 6) / 2)
        (xmin, ymin), (xmax, ymax) = region
        x0, y0 = math.ceil(round(xmin * MILLI, 6)), math.ceil(round(ymin * MILLI, 6))
        width, depth = math.floor(round(xmax * MILLI, 6)) - x0, math.floor(round(ymax * MILLI, 6)) - y0
        columns, rows = max(width, 0) // pitch_mm, max(depth, 0) // pitch_mm
        x0 += (width - columns * pitch_mm) // 2  # the cells centred in the region
        y0 += (depth - rows * pitch_mm) // 2
        centres = tuple((x0 + i * pitch_mm + pitch_mm // 2, y0 + j * pitch_mm + pitch_mm // 2)
                        for j in range(rows) for i in range(columns))
        return cls(centres, columns, rows, pitch_mm / MILLI, clearance)

    @property
    def inner(self) -> float:
        """Half the side of the part of a cell a model may cover."""
        return (self.pitch - self.clearance) / 2.0

    def free(self, keep_out: Sequence[Rectangle]) -> tuple[tuple[int, int], ...]:
        """The cells whose inner part does not reach into any of the `keep_out` rectangles."""
        inner = self.inner

        def clear(centre: tuple[int, int]) -> bool:
            x, y = centre[0] / MILLI, centre[1] / MILLI
            return not any(x - inner < xmax and x + inner > xmin and y - inner < ymax and y + inner > ymin
                           for xmin, ymin, xmax, ymax in keep_out)

        return tuple(centre for centre in self.centres if clear(centre))

    def most_blocked(self, side: float) -> int:
        """The most cells a keep-out square of `side` m (clearance included) can block, wherever it is: the
        inner parts of the cells it reaches along an axis lie in an open interval of `side - clearance +
        pitch` m."""
        per_axis = math.ceil((side - self.clearance) / self.pitch) + 1
        return min(per_axis, self.columns) * min(per_axis, self.rows)


def _keep_out(scenario: Scenario, footprint: tuple[float, float], clearance: float) -> tuple[Rectangle, Rectangle]:
    """Where no model may be: the bounds of the robot's footprint at its start (at the start heading) and
    standing on the goal (at any heading), each grown by `clearance`."""
    length, width = footprint
    c, s = abs(math.cos(scenario.start.yaw)), abs(math.sin(scenario.start.yaw))
    hx = length / 2.0 * c + width / 2.0 * s + clearance
    hy = length / 2.0 * s + width / 2.0 * c + clearance
    x, y = scenario.start.x, scenario.start.y
    reach = math.hypot(length, width) / 2.0 + clearance
    gx, gy = scenario.goal[0], scenario.goal[1]
    return (x - hx, y - hy, x + hx, y + hy), (gx - reach, gy - reach, gx + reach, gy + reach)


def _too_many(count: int, needed: int, region: Region, grid: _Grid, widest: float, blocked: int, why: str) -> str:
    (xmin, ymin), (xmax, ymax) = region
    side = math.ceil(math.ceil(math.sqrt(needed + blocked)) * grid.pitch * 10.0) / 10.0  # k x k cells, to 0.1 m
    kept = f"; {why} {blocked} of them free" if blocked else ""
    return (
        f"worlds(count={count}): {needed} model(s) need {needed} cell(s) of {grid.pitch:g} x {grid.pitch:g} m "
        f"(the widest footprint, {widest:.3g} m, plus the clearance, {grid.clearance:g} m), but the region, "
        f"{xmax - xmin:g} x {ymax - ymin:g} m, holds {grid.columns} x {grid.rows} cells{kept}: room for "
        f"{len(grid.centres) - blocked}. Use a larger region (about {side:g} x {side:g} m), fewer models, "
        "smaller models (size=(lo, hi)) or a smaller clearance."
    )


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


def _name(base: str, index: int) -> str:
    """`base_index`, unique since the index is (the part after the last underscore is the index)."""
    suffix = f"_{index}"
    return base[:MAX_NAME_LENGTH - len(suffix)] + suffix


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
