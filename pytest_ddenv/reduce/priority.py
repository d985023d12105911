"""Priority schemas: the order in which the parts of one round are tried (Table I of the paper).

A schema scores each part; parts are tried in ascending score (the part most likely to hold the cause of
the failure first), ties in file order (the part whose first element comes first). Distances are from
trace points to the elements' real surfaces (the geometry's distance function), one world frame; the
distance of a part is that of its closest element. A schema without the information it needs (no
geometry, no trace, T = 0, nothing sensed) orders like `sequential`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.context import Context

Part = tuple[str, ...]


class Prioritizer(Protocol):
    """A priority schema."""

    @property
    def name(self) -> str: ...

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]: ...


def _by_score(parts: Sequence[Part], scores: Sequence[float], context: Context) -> list[Part]:
    ranked = sorted(range(len(parts)), key=lambda i: (scores[i], context.order(parts[i][0])))
    return [parts[i] for i in ranked]


def _sequential(parts: Sequence[Part], context: Context) -> list[Part]:
    return _by_score(parts, [0.0] * len(parts), context)


def _flatten(parts: Sequence[Part]) -> tuple[list[str], list[int]]:
    names = [name for part in parts for name in part]
    owners = [i for i, part in enumerate(parts) for _ in part]
    return names, owners


def _min_per_part(values: np.ndarray, owners: list[int], count: int) -> np.ndarray:
    """values (..., E) -> (..., count): the minimum over each part's columns."""
    result = np.full((*values.shape[:-1], count), np.inf)
    for column, owner in enumerate(owners):
        result[..., owner] = np.minimum(result[..., owner], values[..., column])
    return result


@dataclass(frozen=True)
class RandomPriority:
    """`random`: a seeded shuffle, different each round, identical for the same seed."""

    name: str = "random"

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]:
        canonical = _sequential(parts, context)
        generator = np.random.default_rng([context.seed, round_index])
        return [canonical[i] for i in generator.permutation(len(canonical))]


@dataclass(frozen=True)
class SequentialPriority:
    """`sequential`: file order."""

    name: str = "sequential"

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]:
        return _sequential(parts, context)


@dataclass(frozen=True)
class FailureProximalPriority:
    """`failure-proximal`: closest to where the latest failure happened (failure position, else last pose)."""

    name: str = "failure-proximal"

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]:
        point = context.failure_point()
        if point is None:
            return _sequential(parts, context)
        names, owners = _flatten(parts)
        distances = context.point_distances(point, names)
        if distances is None:
            return _sequential(parts, context)
        return _by_score(parts, _min_per_part(distances, owners, len(parts)).tolist(), context)


@dataclass(frozen=True)
class TrajectoryPriority:
    """`avg-trajectory-proximal` (mean over trace points of the distance to the part) or
    `min-trajectory-proximal` (smallest distance between any trace point and the part): closest part first."""

    name: str = "avg-trajectory-proximal"

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]:
        names, owners = _flatten(parts)
        distances = context.trace_distances(names)
        if distances is None:
            return _sequential(parts, context)
        per_point = _min_per_part(distances, owners, len(parts))
        scores = per_point.min(axis=0) if self.name == "min-trajectory-proximal" else per_point.mean(axis=0)
        return _by_score(parts, scores.tolist(), context)


@dataclass(frozen=True)
class TimestepPriority:
    """`timestep`: the part with an element the robot sensed earliest first; never-sensed parts last."""

    name: str = "timestep"

    def __call__(self, parts: Sequence[Part], context: Context, round_index: int) -> list[Part]:
        if context.trace is None:
            return _sequential(parts, context)
        sensed = context.trace.first_sensed
        scores = [min((sensed.get(name, np.inf) for name in part), default=np.inf) for part in parts]
        return _by_score(parts, scores, context)


PRIORITY_SCHEMAS: dict[str, Callable[[], Prioritizer]] = {
    "random": RandomPriority,
    "sequential": SequentialPriority,
    "failure-proximal": FailureProximalPriority,
    "avg-trajectory-proximal": lambda: TrajectoryPriority("avg-trajectory-proximal"),
    "min-trajectory-proximal": lambda: TrajectoryPriority("min-trajectory-proximal"),
    "timestep": TimestepPriority,
}
PRIORITIES: tuple[str, ...] = tuple(PRIORITY_SCHEMAS)
PRIORITY_ALIASES = {
    "crash-proximal": "failure-proximal",
    "avg-trajectory": "avg-trajectory-proximal",
    "min-trajectory": "min-trajectory-proximal",
    "timestep-first-sensed": "timestep",
}


def make_prioritizer(priority: str | Prioritizer) -> Prioritizer:
    """The schema for a name (canonical or one of the paper's short names), or a Prioritizer object."""
    if not isinstance(priority, str):
        if callable(priority) and isinstance(getattr(priority, "name", None), str):
            return priority
        raise ReductionError(
            f"priority must be one of {', '.join(PRIORITIES)} or a Prioritizer object, got {priority!r}"
        )
    name = PRIORITY_ALIASES.get(priority, priority)
    if name not in PRIORITY_SCHEMAS:
        raise ReductionError(
            f"unknown priority schema {priority!r}; valid choices: {', '.join(PRIORITIES)} "
            f"(aliases: {', '.join(f'{a}={c}' for a, c in PRIORITY_ALIASES.items())})"
        )
    return PRIORITY_SCHEMAS[name]()
