"""The project's exception hierarchy: every error a user can cause is a `DdenvError`."""

from __future__ import annotations

from pathlib import Path


class DdenvError(Exception):
    """Base class of every error pytest-ddenv raises on purpose."""


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

    def _render(self) -> str:
        where: list[str] = []
        if self.source is not None:
            where.append(self.source if self.line is None else f"{self.source}:{self.line}")
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
