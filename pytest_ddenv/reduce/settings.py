"""Eager validation of `reduce`'s arguments into one frozen `Settings` value."""

from __future__ import annotations

import concurrent.futures
import os
from collections.abc import Callable, Collection, MutableMapping, Sequence
from dataclasses import dataclass
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.deflake import DeflakePolicy, make_policy
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.partition import Partitioner, make_partitioner
from pytest_ddenv.reduce.priority import Prioritizer, make_prioritizer
from pytest_ddenv.reduce.types import (
    Geometry,
    Precondition,
    Probe,
    ProgressEvent,
    Trace,
)
from pytest_ddenv.validation import is_integral, is_real

GRANULARITIES: tuple[str, ...] = ("ddmin", "paper")
COMPLEMENT_ORDERS: tuple[str, ...] = ("reverse", "priority")


@dataclass(frozen=True)
class Settings:
    elements: tuple[str, ...]
    keep: frozenset[str]
    probe: Probe
    geometry: Geometry | None
    reference: Trace | None
    partitioner: Partitioner
    prioritizer: Prioritizer
    n_partitions: int
    granularity: str
    complement_order: str
    policy: DeflakePolicy
    preconditions: tuple[Precondition, ...]
    max_probes: int | None
    max_seconds: float | None
    seed: int
    cache: MutableMapping[Any, Any] | None
    executor: concurrent.futures.Executor | None
    log: ProbeLog | str | os.PathLike[str] | None
    failure_rate_runs: int
    on_progress: Callable[[ProgressEvent], None] | None

    @property
    def reducible(self) -> tuple[str, ...]:
        return tuple(name for name in self.elements if name not in self.keep)


def _int(name: str, value: object, minimum: int) -> int:
    if not is_integral(value) or int(value) < minimum:
        raise ReductionError(f"{name} must be an int >= {minimum}, got {value!r}")
    return int(value)


def _choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ReductionError(f"{name} must be one of {', '.join(choices)}, got {value!r}")
    return str(value)


def validate(
    elements: Sequence[str],
    probe: Probe,
    *,
    geometry: Geometry | None,
    reference: Trace | None,
    partition: str | Partitioner,
    priority: str | Prioritizer,
    n_partitions: int,
    granularity: str,
    complement_order: str,
    deflake: int | str | DeflakePolicy,
    confidence: float,
    keep: Collection[str],
    preconditions: Sequence[Precondition],
    max_probes: int | None,
    max_seconds: float | None,
    seed: int,
    cache: MutableMapping[Any, Any] | None,
    executor: concurrent.futures.Executor | None,
    log: ProbeLog | str | os.PathLike[str] | None,
    failure_rate_runs: int,
    on_progress: Callable[[ProgressEvent], None] | None,
) -> Settings:
    """Check every argument; raise ReductionError naming the argument, the value and what is allowed."""
    if isinstance(elements, (str, bytes)) or not isinstance(elements, Sequence):
        raise ReductionError(f"elements must be a sequence of element names, got {type(elements).__name__}")
    names = tuple(elements)
    for name in names:
        if not isinstance(name, str) or not name:
            raise ReductionError(f"every element must be a non-empty str name, got {name!r}")
    duplicates = sorted({name for name in names if names.count(name) > 1}) if len(set(names)) != len(names) else []
    if duplicates:
        raise ReductionError(f"element names must be unique; repeated: {', '.join(duplicates)}")
    if not callable(probe):
        raise ReductionError(f"probe must be a callable probe(candidate, attempt) -> Observation, got {probe!r}")
    if isinstance(keep, str):
        raise ReductionError(f"keep must be a collection of element names, not the string {keep!r}")
    kept = frozenset(keep)
    unknown = sorted(kept - set(names))
    if unknown:
        raise ReductionError(f"keep names elements that are not in the world: {', '.join(unknown)}")
    if geometry is not None and not (
        callable(getattr(geometry, "centroids", None)) and callable(getattr(geometry, "distances", None))
    ):
        raise ReductionError("geometry must provide centroids(names) and distances(points, names), or be None")
    if reference is not None and not isinstance(reference, Trace):
        raise ReductionError(f"reference must be a Trace or None, got {type(reference).__name__}")
    checks = tuple(preconditions)
    for check in checks:
        if not callable(check):
            raise ReductionError(f"every precondition must be callable(candidate) -> str | None, got {check!r}")
    if max_seconds is not None and (
        not is_real(max_seconds) or not max_seconds >= 0
    ):  # `not >= 0` also refuses NaN
        raise ReductionError(f"max_seconds must be None or a number >= 0, got {max_seconds!r}")
    if cache is not None and not isinstance(cache, MutableMapping):
        raise ReductionError(f"cache must be None or a MutableMapping, got {type(cache).__name__}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise ReductionError(f"executor must be None or a concurrent.futures.Executor, got {executor!r}")
    if log is not None and not isinstance(log, (ProbeLog, str, os.PathLike)):
        raise ReductionError(f"log must be None, a path or a ProbeLog, got {type(log).__name__}")
    if on_progress is not None and not callable(on_progress):
        raise ReductionError(f"on_progress must be None or callable(ProgressEvent), got {on_progress!r}")
    return Settings(
        elements=names,
        keep=kept,
        probe=probe,
        geometry=geometry,
        reference=reference,
        partitioner=make_partitioner(partition),
        prioritizer=make_prioritizer(priority),
        n_partitions=_int("n_partitions", n_partitions, 2),
        granularity=_choice("granularity", granularity, GRANULARITIES),
        complement_order=_choice("complement_order", complement_order, COMPLEMENT_ORDERS),
        policy=make_policy(deflake, confidence),
        preconditions=checks,
        max_probes=None if max_probes is None else _int("max_probes", max_probes, 0),
        max_seconds=None if max_seconds is None else float(max_seconds),
        seed=_int("seed", seed, 0),
        cache=cache,
        executor=executor,
        log=log,
        failure_rate_runs=_int("failure_rate_runs", failure_rate_runs, 0),
        on_progress=on_progress,
    )
