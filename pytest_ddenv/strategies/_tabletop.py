"""`tabletop_worlds()`: an arm at the edge of a table, a target to pick, a place region, and clutter.

The layout, in the world frame: the arm's base at the origin on the table top (z = the table's height),
heading +x; the table a static box reaching `TABLE_MARGIN` behind the base's disc (`base_radius`) and
`table_size[0]` in all along x, centred on y = 0. The target and the place region are drawn in polar
coordinates around the base (a planar distance within `reach`, a bearing within `spread` degrees of +x),
far enough apart in bearing that the target never touches the place region. The clutter is `worlds()`'s: a
list of drafts placed one to a cell of a grid over the table top (the table top is their ground), never in a
cell that reaches the arm's base, the target or the place region (unless `overlap`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from pytest_ddenv.errors import shown
from pytest_ddenv.strategies._arguments import (
    _checked_count,
    _checked_flag,
    _checked_number,
    _checked_range,
    _fail,
    _milli,
)
from pytest_ddenv.strategies._bodies import SIZES, _Body, _draw_physics, _draw_sizes, _primitive, _Primitives
from pytest_ddenv.strategies._defaults import MILLI, PRIMITIVE_KINDS, PrimitiveKind, Range
from pytest_ddenv.strategies._drawing import _Draft, _drafts, _draw_milli, _draw_yaw, _World
from pytest_ddenv.strategies._grid import Rectangle, _Grid
from pytest_ddenv.strategies._plans import _call, _Plan, _WorldPlan
from pytest_ddenv.validation import is_real
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import ArmDescription, Ground, Model, Physics, Pose, Scenario, Shape, World

PANDA_BASE_RADIUS = 0.16
"""The radius (m) of a disc around the built-in Panda's base origin that holds its base link's footprint
(the collision mesh of `panda_link0` spans x -0.154..0.072, y -0.095..0.095 m)."""
TABLE_MARGIN = 0.04
"""How far (m) the table reaches beyond the base's disc behind the base: the base link stands on the table."""
TARGET_KINDS: tuple[PrimitiveKind, ...] = ("box", "cylinder")
"""What a drawn target is: something a parallel gripper closes on."""
TABLE = "table"
TARGET = "target"


@dataclass(frozen=True, repr=False)
class _TabletopPlan(_Plan):
    """Everything `tabletop_worlds()` checked, ready to draw from."""

    arm: str | ArmDescription
    table: Model
    top: float
    reach: tuple[int, int]
    """Planar distance from the base to the target and to the place region's centre, in mm."""
    spread: int
    """The largest bearing from +x (whole degrees) of the target and the place region's centre."""
    apart: int
    """The smallest bearing difference (whole degrees) that keeps the target off the place region."""
    target: _Primitives
    place_tolerance: float
    clutter: _WorldPlan
    """The clutter, drawn and placed as `worlds()` does, on a grid over the table top."""
    height: tuple[int, int] | None
    """The clutter's heights (boxes, cylinders) in mm; None: as drawn in `size`."""
    base_keep_out: Rectangle
    timeout: float
    physics: Physics
    name: str


def tabletop_worlds(
    arm: str | ArmDescription = "panda",
    *,
    count: int | tuple[int, int] = (0, 10),
    table_size: tuple[float, float] = (1.0, 1.4),
    table_height: float = 0.4,
    reach: Range = (0.35, 0.65),
    spread: float = 60.0,
    target_size: Range = (0.04, 0.06),
    target_mass: Range = (0.05, 0.2),
    place_tolerance: float = 0.08,
    kinds: Sequence[PrimitiveKind] = PRIMITIVE_KINDS,
    size: Range = (0.03, 0.12),
    height: Range | None = None,
    mass: Range = (0.05, 1.0),
    friction: Range = (0.5, 1.0),
    static: bool | None = False,
    yaw: bool = True,
    clearance: float = 0.03,
    overlap: bool = False,
    base_radius: float | None = None,
    timeout: float = 20.0,
    physics: Physics = Physics(),
    name: str = "tabletop",
) -> st.SearchStrategy[World]:
    """Worlds of an arm picking a target from a cluttered table and placing it in a place region.

    `arm` (a registered arm's name, "panda" by default, or an `ArmDescription`) stands at the origin on the
    table top, heading +x. The table is a static box, `table_size` (depth along x, width along y, m) and its
    top at `table_height`, reaching `TABLE_MARGIN` m behind the base's disc. The target ("target": a dynamic
    box or upright cylinder, every side or diameter in `target_size`, mass in `target_mass`) and the centre
    of the place region (the scenario's goal, radius `place_tolerance`) are each drawn at a planar distance
    in `reach` from the base and a bearing within `spread` degrees of +x, apart by at least `clearance`.

    `count` clutter models (a number, or a (lo, hi) range) drawn as by `worlds(kinds=, size=, mass=,
    friction=, static=, yaw=)` (the heights of boxes and cylinders in `height` when given) stand upright on
    the table top (their lowest point on it), inside it, at least `clearance` m from each other, the target,
    the place region and the arm's base (a disc of `base_radius` m, known for the Panda); with `overlap`,
    they may overlap each other, the target and the place region, never the base. Names: "box_0",
    "cylinder_1", ... The scenario names the target, the table and every clutter model as watched
    (`Scenario.watch`); `timeout` is in simulated seconds.

    Raises InvalidArgument at once when the table cannot hold what is asked.
    """
    call = _call(tabletop_worlds, locals())
    arm = _checked_arm(arm)
    radius = _checked_base_radius(arm, base_radius)
    inset = radius + TABLE_MARGIN
    depth, width = _checked_table_size(table_size, inset)
    top = _checked_number("tabletop_worlds", "table_height", table_height, low_included=False)
    near, far = _milli("tabletop_worlds", "reach", _checked_range("tabletop_worlds", "reach", reach))
    bearing = _checked_number("tabletop_worlds", "spread", spread)
    if bearing > 90.0:
        raise _fail("tabletop_worlds", "spread", f"expected at most 90 degrees (beside the arm), got {spread!r}")
    target = _Primitives.checked("tabletop_worlds", TARGET_KINDS, target_size, target_mass, friction, False, yaw)
    tolerance = _checked_number("tabletop_worlds", "place_tolerance", place_tolerance, low_included=False)
    clutter = _Primitives.checked("tabletop_worlds", kinds, size, mass, friction, static, yaw)
    heights = None if height is None else _milli("tabletop_worlds", "height",
                                                 _checked_range("tabletop_worlds", "height", height))
    counts = _checked_count(count, "tabletop_worlds")
    gap = _checked_number("tabletop_worlds", "clearance", clearance)
    overlaps = _checked_flag("tabletop_worlds", "overlap", overlap)
    limit = _checked_number("tabletop_worlds", "timeout", timeout, low_included=False)
    if not isinstance(physics, Physics):
        raise _fail("tabletop_worlds", "physics", f"expected a Physics, got {shown(physics)}")
    if name_problem(name) is not None:
        raise _fail("tabletop_worlds", "name", f"{name_problem(name)}, got {shown(name)}")

    table_region = ((-inset, -width / 2.0), (depth - inset, width / 2.0))
    target_radius = target.size[1] / MILLI * math.sqrt(2.0) / 2.0  # a box's half diagonal bounds both kinds
    _check_workspace(table_region, radius, (near / MILLI, far / MILLI), bearing, max(target_radius, tolerance), gap)
    apart = _bearing_apart(near / MILLI, target_radius + tolerance + gap, bearing)
    table = Model(TABLE, (Shape("box", size=(depth, width, top)),),
                  pose=Pose(depth / 2.0 - inset, 0.0, top / 2.0), static=True)
    widest = clutter.widest() if clutter.kinds else 0.0
    grid = _Grid.of(table_region, widest, gap)
    reach_out = radius + gap
    base_keep_out = (-reach_out, -reach_out, reach_out, reach_out)
    plan = _TabletopPlan(
        arm=arm, table=table, top=top, reach=(near, far), spread=math.floor(bearing), apart=apart, target=target,
        place_tolerance=tolerance,
        clutter=_WorldPlan(scenario=None, count=counts, grid=grid, free=None, primitives=clutter, templates=(),
                           clearance=gap, overlap=overlaps, stacked=0, footprint=None, ground=Ground(z=top),
                           physics=physics, name=name, call=call),
        height=heights,
        base_keep_out=base_keep_out, timeout=limit, physics=physics, name=name, call=call)
    if counts[1] and not clutter.kinds:
        raise _fail("tabletop_worlds", "kinds", "no kinds: nothing to draw the clutter from (or give count=0)")
    _check_room(plan, widest, 2.0 * (target_radius + gap), 2.0 * (tolerance + gap))
    return _Drawn.tabletop_worlds(plan)


def _checked_arm(arm: object) -> str | ArmDescription:
    if isinstance(arm, ArmDescription) or (isinstance(arm, str) and name_problem(arm) is None):
        return arm
    raise _fail("tabletop_worlds", "arm", f"expected a registered arm's name or an ArmDescription, got {shown(arm)}")


def _checked_base_radius(arm: str | ArmDescription, base_radius: object) -> float:
    if base_radius is not None:
        return _checked_number("tabletop_worlds", "base_radius", base_radius, low_included=False)
    if arm == "panda":
        return PANDA_BASE_RADIUS
    label = arm if isinstance(arm, str) else arm.label
    raise _fail("tabletop_worlds", "base_radius", f"the arm is {label!r}, whose base the world model does not "
                                                  "know: pass base_radius= (m, a disc around the base's origin "
                                                  "that holds its footprint)")


def _checked_table_size(table_size: object, inset: float) -> tuple[float, float]:
    if not (isinstance(table_size, (tuple, list)) and len(table_size) == 2
            and all(is_real(v) and math.isfinite(v) and v > 0 for v in table_size)):
        raise _fail("tabletop_worlds", "table_size", f"expected (depth, width) in m, two numbers > 0, got "
                                                     f"{shown(table_size)}")
    depth, width = float(table_size[0]), float(table_size[1])
    if depth <= inset:
        raise _fail("tabletop_worlds", "table_size", f"the depth {depth:g} m leaves no room in front of the arm "
                                                     f"(the table reaches {inset:g} m behind its base's centre)")
    return depth, width


def _check_workspace(table: tuple[tuple[float, float], tuple[float, float]], base: float, reach: Range,
                     spread: float, radius: float, gap: float) -> None:
    """The target and the place region, anywhere they can be drawn, stay on the table and off the base."""
    (xmin, ymin), (xmax, ymax) = table
    near, far = reach
    if near < base + gap + radius:
        raise _fail("tabletop_worlds", "reach", f"the nearest distance {near:g} m puts the target or the place "
                                                f"region on the arm's base: use at least {base + gap + radius:.3g}"
                                                " m (the base's radius, the clearance and the largest target or "
                                                "place radius)")
    turn = math.radians(spread)
    lowest_x = min(near * math.cos(turn), far * math.cos(turn))
    widest_y = far * math.sin(turn)
    if far + radius > xmax or lowest_x - radius < xmin or widest_y + radius > min(ymax, -ymin):
        raise _fail("tabletop_worlds", "table_size",
                    f"the table, x {xmin:g}..{xmax:g} m and y {ymin:g}..{ymax:g} m around the arm's base, does "
                    f"not hold the targets and place regions drawn up to {far:g} m from the base and {spread:g} "
                    "degrees from +x: use a larger table_size, a smaller reach or spread")


def _bearing_apart(near: float, distance: float, spread: float) -> int:
    """The smallest bearing difference (whole degrees) between two points at least `near` m from the base that
    puts them at least `distance` m apart (the chord 2 near sin(angle / 2))."""
    if distance >= 2.0 * near:
        raise _fail("tabletop_worlds", "reach", f"points {near:g} m from the base cannot be {distance:.3g} m apart "
                                                "(the target, the place region and the clearance between them): "
                                                "use a larger nearest reach")
    apart = math.ceil(math.degrees(2.0 * math.asin(distance / (2.0 * near))))
    if apart > math.floor(spread):
        raise _fail("tabletop_worlds", "spread", f"the target and the place region need {apart} degrees between "
                                                 f"them, more than spread={spread:g} allows on either side: use a "
                                                 "larger spread or reach, a smaller place_tolerance or target")
    return apart


def _check_room(plan: _TabletopPlan, widest: float, target_side: float, place_side: float) -> None:
    """InvalidArgument when the grid, beside the base and wherever the target and place region are drawn,
    cannot hold the most clutter `count` allows (one when it may overlap)."""
    clutter = plan.clutter
    grid, counts = clutter.grid, clutter.count
    blocked = len(grid.centres) - len(grid.free([plan.base_keep_out]))
    if not clutter.overlap:
        blocked += grid.most_blocked(target_side) + grid.most_blocked(place_side)
    needed = min(counts[1], 1) if clutter.overlap else counts[1]
    if needed > len(grid.centres) - blocked:
        raise InvalidArgument(
            f"tabletop_worlds(count={counts[1]}): {needed} clutter model(s) need {needed} cell(s) of "
            f"{grid.pitch:g} x {grid.pitch:g} m (the widest footprint, {widest:.3g} m, plus the clearance, "
            f"{grid.clearance:g} m), but the table top holds {grid.columns} x {grid.rows} cells, of which the arm's "
            f"base, the target and the place region may keep {blocked} free: room for "
            f"{max(len(grid.centres) - blocked, 0)}. Use a larger table_size, fewer models, smaller models "
            "(size=(lo, hi)) or a smaller clearance.")


@dataclass(frozen=True)
class _Layout:
    """Where the target and the place region's centre are drawn."""

    target: Model
    place: tuple[float, float]


def _polar(distance_mm: int, bearing_degrees: int) -> tuple[float, float]:
    """A point at `distance_mm` from the origin and `bearing_degrees` from +x, in whole millimetres, in m."""
    turn = math.radians(bearing_degrees)
    return round(distance_mm * math.cos(turn)) / MILLI, round(distance_mm * math.sin(turn)) / MILLI


@st.composite
def _layouts(draw: st.DrawFn, plan: _TabletopPlan) -> _Layout:
    """The target (shrinks toward a box straight ahead, in the middle of the reach, heading 0) and the place
    region (toward the nearest bearing beside the target's, on the positive side first)."""
    spec, (near, far) = plan.target, plan.reach
    kind = spec.kinds[draw(st.integers(0, len(spec.kinds) - 1))]
    sizes = _draw_sizes(draw, spec, "box")[:SIZES[kind]]  # as many draws whatever the kind (see `_drafts`)
    body: _Body = _draw_physics(draw, spec).of(_primitive(kind, sizes))
    heading = _draw_yaw(draw) if spec.yaw and kind == "box" else 0.0
    distance = _draw_milli(draw, near, far, towards=(near + far) // 2)
    bearing = _draw_milli(draw, -plan.spread, plan.spread, towards=0)
    x, y = _polar(distance, bearing)
    target = body.placed(TARGET, x, y, plan.top, heading)
    allowed = [b for b in range(-plan.spread, plan.spread + 1) if abs(b - bearing) >= plan.apart]
    allowed.sort(key=lambda b: (abs(b - bearing), b < bearing))
    place_bearing = allowed[draw(st.integers(0, len(allowed) - 1))]
    place_distance = _draw_milli(draw, near, far, towards=(near + far) // 2)
    return _Layout(target, _polar(place_distance, place_bearing))


def _keep_outs(plan: _TabletopPlan, layout: _Layout, world_of_target: World) -> list[Rectangle]:
    """Where no clutter may be: the base, and unless clutter may overlap, the target's and the place region's
    bounds, each grown by the clearance."""
    keep_out = [plan.base_keep_out]
    if not plan.clutter.overlap:
        gap = plan.clutter.clearance
        low, high = world_of_target.bounds(TARGET)
        keep_out.append((low[0] - gap, low[1] - gap, high[0] + gap, high[1] + gap))
        reach_out = plan.place_tolerance + gap
        x, y = layout.place
        keep_out.append((x - reach_out, y - reach_out, x + reach_out, y + reach_out))
    return keep_out


class _Drawn:
    """The composite strategy, named as the public function, so that Hypothesis shows
    `tabletop_worlds(count=(3, 12))` in its messages."""

    @staticmethod
    @st.composite
    def tabletop_worlds(draw: st.DrawFn, plan: _TabletopPlan) -> World:
        """The clutter's drafts first (a list: Hypothesis shrinks a world by deleting any of them), then the
        target and the place region, then the drafts placed on the free cells of the table top."""
        return _placed(plan, draw(st.lists(_drafts(plan.clutter), min_size=plan.clutter.count[0],
                                           max_size=plan.clutter.count[1])), draw(_layouts(plan)))


def _placed(plan: _TabletopPlan, drafts: Sequence[_Draft], layout: _Layout) -> World:
    clutter = plan.clutter
    free = clutter.grid.free(_keep_outs(plan, layout, World(models=(layout.target,))))
    placed = _World(clutter, None, frozenset(free)).placed([_with_height(plan, draft) for draft in drafts])
    names = placed.names
    scenario = Scenario(robot=plan.arm, start=Pose(0.0, 0.0, plan.top), start_z_given=True,
                        goal=(layout.place[0], layout.place[1], None), goal_tolerance=plan.place_tolerance,
                        timeout=plan.timeout, target=TARGET, table=TABLE, watch=names)
    return World(models=(plan.table, layout.target, *placed.models), scenario=scenario, physics=plan.physics,
                 name=plan.name)


def _with_height(plan: _TabletopPlan, draft: _Draft) -> _Draft:
    """The draft with its height (a box's third size, a cylinder's second) moved from the `size` range to the
    same place in the `height` range: it shrinks as before, and the footprint, hence the placing, is kept."""
    spec = plan.clutter.primitives
    if plan.height is None or draft.choice >= len(spec.kinds) or spec.kinds[draft.choice] == "sphere":
        return draft
    (lo, hi), (low, high) = spec.size, plan.height
    drawn = draft.sizes[-1]
    scaled = low if hi == lo else low + round((drawn - lo) * (high - low) / (hi - lo))
    return dataclasses.replace(draft, sizes=(*draft.sizes[:-1], scaled))
