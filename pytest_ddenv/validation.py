"""What counts as a number, an integer or a flag in every input pytest-ddenv checks, and how a wrong one is told.

Python's `bool` is an `int`, numpy's scalars are not Python numbers, and a float can be NaN or infinite:
each check below settles those cases once, so that a world file, a marker argument, an option and a keyword
argument accept the same values. The callers raise their own error (`WorldError`, `MarkerError`,
`pytest.UsageError`, ...) with the place they know (file, model, field, marker argument, option), and
`expected` words that error the same way everywhere: "{where}: expected {what}, got {value}".
"""

from __future__ import annotations

import math
import numbers
from typing import Any, TypeGuard

from pytest_ddenv.errors import shown


def is_flag(value: Any) -> TypeGuard[bool]:
    """True or False (not 1, 0 or "yes")."""
    return isinstance(value, bool)


def is_number(value: Any) -> TypeGuard[int | float]:
    """A Python int or float, not a bool (NaN and infinities included: see `is_finite_number`)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite_number(value: Any) -> TypeGuard[int | float]:
    """A Python int or float, not a bool, neither NaN nor infinite (an int too large for a float counts)."""
    if not is_number(value):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return True


def is_real(value: Any) -> TypeGuard[float]:
    """A real number of any kind, numpy scalars included, not a bool (typed as float: it compares as one)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value: Any) -> TypeGuard[int]:
    """A Python int, not a bool (and not a float, even 3.0)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_integral(value: Any) -> TypeGuard[int]:
    """An integer of any kind, numpy integers included, not a bool (typed as int: it computes as one)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def expected(what: str, value: object, where: str = "", *, got: str | None = None) -> str:
    """The message for a value that is not what it should be: ``"{where}: expected {what}, got {value}"``.

    `value` is shown clipped (`errors.shown`), or `got` says what it was instead where a description tells
    more ("a 5000-digit number"). `where` names the place: the argument, option, marker argument or field;
    leave it out when the error names the place itself (`WorldError(field=...)`).
    """
    message = f"expected {what}, got {shown(value) if got is None else got}"
    return f"{where}: {message}" if where else message


def at_least(value: Any, minimum: int, *, text: bool = False) -> int | None:
    """`value` as an integer >= `minimum`, or None if it is not one (`text`: its digits are read, as an option's
    or an ini key's value is given)."""
    if text and isinstance(value, str):
        try:
            value = int(value)
        except ValueError:  # not digits, or more than Python reads (sys.get_int_max_str_digits)
            return None
    return value if is_integer(value) and value >= minimum else None


def positive_finite(value: Any, *, text: bool = False) -> float | None:
    """`value` as a positive, finite float, or None if it is not one (NaN, an infinity, 0, a negative number, a
    word, an integer too large for a float); `text`: read as a number written out."""
    if text and isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            return None
    if not is_number(value):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) and number > 0 else None
