"""Argument checks, eager as in Hypothesis: the checked value, or InvalidArgument saying what to change."""

from __future__ import annotations

import math

from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from pytest_ddenv.errors import shown
from pytest_ddenv.strategies._defaults import MILLI, PRIMITIVE_KINDS, Point, PrimitiveKind, Range, Region
from pytest_ddenv.validation import is_flag, is_integer, is_real
from pytest_ddenv.world.limits import name_problem
from pytest_ddenv.world.model import Ground, Physics, Scenario


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


def _checked_flag(function: str, argument: str, value: object) -> bool:
    if not is_flag(value):
        raise _fail(function, argument, f"expected True or False, got {value!r}")
    return value


def _checked_number(function: str, argument: str, value: object, *, low: float = 0.0,
                    low_included: bool = True) -> float:
    if not (is_real(value) and math.isfinite(value) and (value >= low if low_included else value > low)):
        bound = f">= {low:g}" if low_included else f"> {low:g}"
        raise _fail(function, argument, f"expected a finite number {bound}, got {value!r}")
    return float(value)


def _checked_probability(function: str, argument: str, value: object) -> float:
    chance = _checked_number(function, argument, value)
    if chance > 1.0:
        raise _fail(function, argument, f"expected a probability from 0 to 1, got {value!r}")
    return chance


def _milli(function: str, argument: str, bounds: Range) -> tuple[int, int]:
    """The range in thousandths, rounded inward; InvalidArgument when it holds no whole thousandth."""
    lo, hi = math.ceil(round(bounds[0] * MILLI, 6)), math.floor(round(bounds[1] * MILLI, 6))
    if lo > hi:
        raise _fail(function, argument, f"{bounds!r} holds no multiple of {1 / MILLI:g} (values are drawn in "
                                        "thousandths); widen it")
    return lo, hi


def _checked_count(count: object, function: str = "worlds") -> tuple[int, int]:
    if is_integer(count):
        counts = (count, count)
    elif isinstance(count, (tuple, list)) and len(count) == 2 and all(is_integer(c) for c in count):
        counts = (count[0], count[1])
    else:
        raise _fail(function, "count", f"expected a whole number or a pair (lowest, highest), got {shown(count)}")
    if counts[0] < 0 or counts[0] > counts[1]:
        raise _fail(function, "count", f"expected 0 <= lowest <= highest, got {count!r}")
    return counts


def _checked_footprint(footprint: object) -> tuple[float, float]:
    if not (isinstance(footprint, (tuple, list)) and len(footprint) == 2
            and all(is_real(v) and math.isfinite(v) and v > 0 for v in footprint)):
        raise _fail("worlds", "robot_footprint", f"expected (length, width) in m, two numbers > 0, got "
                                                 f"{shown(footprint)}")
    return float(footprint[0]), float(footprint[1])


def _checked_world_parts(scenario: Scenario | st.SearchStrategy[Scenario] | None, ground: Ground | None,
                         physics: Physics, name: str) -> None:
    """The arguments of `worlds()` that go into the World as they are: of the right types, `name` valid."""
    if ground is not None and not isinstance(ground, Ground):
        raise _fail("worlds", "ground", f"expected a Ground or None, got {shown(ground)}")
    if not isinstance(physics, Physics):
        raise _fail("worlds", "physics", f"expected a Physics, got {shown(physics)}")
    if name_problem(name) is not None:
        raise _fail("worlds", "name", f"{name_problem(name)}, got {shown(name)}")
    if scenario is not None and not isinstance(scenario, (Scenario, st.SearchStrategy)):
        raise _fail("worlds", "scenario", f"expected a Scenario, a strategy of Scenarios or None, got "
                                          f"{shown(scenario)}")
