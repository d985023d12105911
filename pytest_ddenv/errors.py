"""The project's exception hierarchy: every error a user can cause is a `DdenvError`."""

from __future__ import annotations

import re
import reprlib
from pathlib import Path
from typing import Any

SHOWN_CHARACTERS = 60
"""The most characters of user data (a value, a key, a line of a foreign file) an error message shows."""
PATH_CHARACTERS = 240
"""The most characters of a path or URI an error message shows."""


class DdenvError(Exception):
    """Base class of every error pytest-ddenv raises on purpose."""

    def shown_from(self, folder: Path) -> str:
        """The message, with the file it names relative to `folder` when it is inside it (shorter lines)."""
        return str(self)


class WorldError(DdenvError):
    """A world file or world value is invalid. The message names the file, the model and the field."""

    def __init__(
        self,
        message: str,
        *,
        source: str | Path | None = None,
        model: str | None = None,
        field: str | None = None,
        line: int | None = None,
    ) -> None:
        self.reason = message
        self.source = str(source) if source is not None else None
        self.model = model
        self.field = field
        self.line = line
        super().__init__(self._render())

    def shown_from(self, folder: Path) -> str:
        if self.source is None or not Path(self.source).is_absolute():
            return str(self)
        try:
            relative = Path(self.source).relative_to(folder)
        except ValueError:
            return str(self)
        full, self.source = self.source, str(relative)
        try:
            return self._render()
        finally:
            self.source = full

    def _render(self) -> str:
        where: list[str] = []
        if self.source is not None:
            source = printable(self.source)
            where.append(source if self.line is None else f"{source}:{self.line}")
        elif self.line is not None:
            where.append(f"line {self.line}")
        if self.model is not None:
            where.append(f"model {self.model}")
        if self.field is not None:
            where.append(f"field '{self.field}'")
        return f"{', '.join(where)}: {self.reason}" if where else self.reason


class ScenarioError(WorldError):
    """The scenario (robot, start, goal, timeout, predicates) cannot be simulated as given."""


class ReductionError(DdenvError):
    """The reduction engine was called with invalid arguments or cannot proceed."""


class ControllerError(DdenvError):
    """The controller under test broke its contract: it returned something that is not a command (or a
    NaN), or its run went past the wall-clock limit. Like any exception of the test, it fails the run; it
    is the failure being reduced only if the original failure was this same error. The one `DdenvError` that
    is the system under test's failure, not pytest-ddenv's (`raised_by_ddenv`)."""


class ControllerTimeout(ControllerError):
    """A run took longer than its wall-clock limit (`max_wall_time`): the controller (or the world) is too
    slow. The simulated time limit did not end it first."""


def raised_by_ddenv(error: BaseException) -> bool:
    """Whether `error` is one pytest-ddenv raised about its input or its own work (a world, a setting, a worker):
    every `DdenvError` but a `ControllerError`, which says what the controller under test did (the test's
    failure, judged like any other exception of the test)."""
    return isinstance(error, DdenvError) and not isinstance(error, ControllerError)


class _ShortRepr(reprlib.Repr):
    """reprlib with small limits, safe for any value: huge integers, bytes, nested or recursive containers."""

    def __init__(self, limit: int) -> None:
        super().__init__()
        self.limit = limit
        self.maxlevel, self.maxlist, self.maxtuple, self.maxdict, self.maxset = 2, 4, 4, 4, 4
        self.maxstring = self.maxother = self.maxlong = limit

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 128:  # repr() of an int of more than 4300 digits raises ValueError
            return f"<an integer of about {int(x.bit_length() * 0.30103) + 1} digits>"
        return super().repr_int(x, level)

    def repr_bytes(self, x: bytes, level: int) -> str:
        head = repr(x[:self.limit])
        return head if len(x) <= self.limit else f"{head[:-1]}...{head[-1]} ({len(x)} bytes)"

    def repr_instance(self, x: Any, level: int) -> str:
        try:
            text = object.__repr__(x) if isinstance(x, BaseException) else repr(x)
        except Exception:  # noqa: BLE001 - a broken __repr__ must not hide the error being reported
            text = f"<{type(x).__name__} object>"
        return text if len(text) <= self.limit else f"{text[:self.limit - 3]}..."


_SHORT_REPR = _ShortRepr(SHOWN_CHARACTERS)


def shown(value: object, limit: int = SHOWN_CHARACTERS) -> str:
    """The repr of user data for an error message, at most about `limit` characters whatever the value's size
    (a whole file read as one string, a billion-element alias structure, a 5000-digit integer): long strings
    keep their start and end, containers their first items, with `...` for what is left out. Give a larger
    `limit` for paths and URIs."""
    text = (_SHORT_REPR if limit == SHOWN_CHARACTERS else _ShortRepr(limit)).repr(value)
    return text if len(text) <= 2 * limit else f"{text[:2 * limit - 3]}..."


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\ud800-\udfff]")


def printable(text: str) -> str:
    """`text` with its control characters (a newline in a file name, ...) escaped as Python writes them
    (`\\n`, `\\x07`): an error message stays one line."""
    return _CONTROL.sub(lambda found: repr(found.group())[1:-1], text)


def shown_path(path: object) -> str:
    """A path (or URI) for an error message, as it is (control characters escaped, see `printable`), clipped to
    about PATH_CHARACTERS characters."""
    text = printable(str(path))
    if len(text) <= PATH_CHARACTERS:
        return text
    half = PATH_CHARACTERS // 2
    return f"{text[:half]}...{text[-half:]}"
