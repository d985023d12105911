"""What one value of a world may be, however the world was made: a number the simulator takes, a name that is
written to SDF and read back unchanged, a timestep, a solver iteration count. Each check returns the problem
in words, or None; the readers and `values` name the file, the model and the field.

pybullet computes in double precision, yet its contacts change from about 1e15 m on (a robot in a box of
1e12 m touches it as in a box of 10 m; in a box of 1e15 m it is found "0.49 m deep", and in a cylinder of
radius 1e38 m it touches nothing) and its bounding boxes overflow past about 1e30. A gravity beyond about
1000 m/s^2 breaks its contacts too (the Husky sinks into the ground, or drives backwards at 10 000 m/s^2).
So every length, coordinate, mass and other value of a world is at most MAX_MAGNITUDE in absolute value, and
each axis of gravity at most MAX_GRAVITY.
"""

from __future__ import annotations

import math
import re
from typing import Any

from pytest_ddenv.errors import shown
from pytest_ddenv.validation import expected, is_finite_number, is_integer, is_real

MAX_MAGNITUDE = 1e9
"""The largest absolute value of a length (m), coordinate (m), mass (kg) or other number of a world."""
MAX_GRAVITY = 100.0
"""The largest absolute value of each axis of gravity (m/s^2; about 10 g)."""


ENGINE_PACKAGES = {"pybullet": ("pybullet", ("pip install pybullet (it has wheels for Python <= 3.11 only: on a "
                                             "later Python it compiles from source, or choose mujoco)")),
                   "mujoco": ("mujoco", 'pip install "pytest-ddenv[mujoco]"')}
"""Each physics engine's Python module and how to install it."""


def engine_problem(engine: Any) -> str | None:
    """Why `engine` cannot simulate a world here (not a known engine, or its package is not installed), or None."""
    import importlib.util

    if not isinstance(engine, str) or engine not in ENGINE_PACKAGES:
        return expected(f"one of {', '.join(ENGINE_PACKAGES)}", engine)
    module, install = ENGINE_PACKAGES[engine]
    if importlib.util.find_spec(module) is None:
        return f"the {engine} physics engine is not installed: {install}"
    return None


def default_engine() -> str:
    """The engine of a world that names none: pybullet where it is installed, otherwise mujoco."""
    import importlib.util

    return "pybullet" if importlib.util.find_spec("pybullet") is not None else "mujoco"


def engine_version(engine: str) -> str:
    """The installed version of an engine's package ("not installed" when it is absent)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(ENGINE_PACKAGES[engine][0])
    except (KeyError, PackageNotFoundError):
        return "not installed"


def magnitude_problem(value: float, limit: float = MAX_MAGNITUDE) -> str | None:
    """Why the finite number `value` is beyond what the simulator takes, or None."""
    if abs(value) <= limit:
        return None
    return (f"expected a number from -{_written(limit)} to {_written(limit)}, got {value:g} (the simulator does "
            "not handle larger numbers)")


def _written(limit: float) -> str:
    return "1e9" if limit == MAX_MAGNITUDE else f"{limit:g}"


def number_problem(value: Any, *, positive: bool = False, non_negative: bool = False,
                   limit: float = MAX_MAGNITUDE) -> str | None:
    """Why `value` is not a number of a world (a real, finite, within `limit`, and positive or non-negative
    when asked), or None."""
    if not is_real(value):
        return expected("a number", value)
    try:
        number = float(value)
    except OverflowError:  # an integer of hundreds of digits
        number = math.inf
    if not math.isfinite(number):
        return expected("a finite number", value)
    if positive and number <= 0:
        return expected("a positive number", number)
    if non_negative and number < 0:
        return expected("a number >= 0", number)
    return magnitude_problem(number, limit)


MAX_NAME_LENGTH = 256
"""Longest model (or world, robot, joint) name."""
MAX_SOLVER_ITERATIONS = 10_000
TIMESTEP_RANGE = (1e-6, 1.0)
"""Smallest and largest simulation timestep (s)."""
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]")


def text_problem(text: str, *, allowed: str = "") -> str | None:
    """Why `text` cannot be a value of a world file (written to SDF as XML and read back), or None: a
    control character (tab and newline included, unless `allowed`) or a lone surrogate."""
    for found in _CONTROL.finditer(text):
        if found.group() not in allowed:
            return f"the control character {found.group()!r} (at position {found.start()}) is not allowed"
    return None


def name_problem(name: str) -> str | None:
    """Why `name` cannot name a model, a world or a robot, or None. Names are written to SDF and read back
    unchanged: no control characters, no blanks at either end, at most MAX_NAME_LENGTH characters."""
    if not name or not name.strip():
        return "a name must not be empty"
    problem = text_problem(name)
    if problem is not None:
        return problem
    if name != name.strip():
        return "a name must not start or end with a blank (SDF readers strip them)"
    if len(name) > MAX_NAME_LENGTH:
        return f"a name is at most {MAX_NAME_LENGTH} characters, this one has {len(name)}"
    return None


def solver_iterations_problem(value: object) -> str | None:
    """Why `value` is not a solver iteration count, or None (a whole number from 1 to MAX_SOLVER_ITERATIONS;
    a float such as 1e3 counts when it is whole)."""
    if not (is_integer(value) or (is_finite_number(value) and float(value).is_integer())) \
            or not 1 <= value <= MAX_SOLVER_ITERATIONS:
        return f"expected a whole number from 1 to {MAX_SOLVER_ITERATIONS}, got {shown(value)}"
    return None


def timestep_problem(value: float) -> str | None:
    """Why `value` (s) is not a simulation timestep, or None."""
    low, high = TIMESTEP_RANGE
    if not low <= value <= high:
        return f"expected a timestep from {low:g} to {high:g} s, got {value:g}"
    return None
