"""`ReductionSettings`, what the caller gives `reduce`, and its eager validation into one frozen `Settings`
value (the checked settings with the probe, the inputs and the services of one reduction)."""

from __future__ import annotations

import concurrent.futures
import os
from collections.abc import Callable, Collection, MutableMapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

from pytest_ddenv import defaults
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
from pytest_ddenv.validation import expected, is_flag, is_integral, is_real

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
    check_independence: bool = False
    workers: int = 1
    """How many probes a round keeps running at once on `executor`."""
    first_cut: frozenset[str] | None = None
    """The elements a first candidate keeps (the driver's cut by reach), tried before the rounds."""
    precondition_check: bool = False

    @property
    def reducible(self) -> tuple[str, ...]:
        return tuple(name for name in self.elements if name not in self.keep)


def _int(name: str, value: object, minimum: int) -> int:
    if not is_integral(value) or int(value) < minimum:
        raise ReductionError(expected(f"an integer >= {minimum}", value, name))
    return int(value)


def _flag(name: str, value: object) -> bool:
    if not is_flag(value):
        raise ReductionError(expected("True or False", value, name))
    return value


def _choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ReductionError(expected(f"one of {', '.join(choices)}", value, name))
    return str(value)


@dataclass(frozen=True)
class ReductionSettings:
    """How `reduce` works: every setting of the engine, with its default (docs/algorithm.md says what each
    does). Strategies may be given as objects: `partition` a `Partitioner`, `priority` a `Prioritizer`,
    `deflake` a `DeflakePolicy`. Checked when `reduce` starts (ReductionError naming the field)."""

    partition: str | Partitioner = defaults.PARTITION
    priority: str | Prioritizer = defaults.PRIORITY
    n_partitions: int = defaults.N_PARTITIONS
    granularity: str = defaults.GRANULARITY
    complement_order: str = "reverse"
    deflake: int | str | DeflakePolicy = defaults.DEFLAKE
    confidence: float = 0.95
    keep: Collection[str] = ()
    preconditions: Sequence[Precondition] = ()
    max_probes: int | None = None
    max_seconds: float | None = None
    seed: int = defaults.SEED
    failure_rate_runs: int = 20
    check_independence: bool = False
    """First run the world without its reducible elements once (those the preconditions need stay); if it
    reproduces f, nothing is reduced (`Reduction.independent`)."""
    workers: int | None = None
    """How many probes a round keeps running at once on the executor (default: the number of CPUs; ignored
    without one)."""
    cache: MutableMapping[Any, Any] | None = None
    """Verdicts shared between reductions of the same elements (candidate -> outcomes)."""
    first_cut: Collection[str] | None = None
    """A first candidate, tried in one trial (deflake rule and all) after the calibration and before the
    rounds: the elements it keeps (the driver's cut by reach, driver/reach.py). When it reproduces f the
    rounds start from it; otherwise from the whole world. None: no first cut."""
    precondition_check: bool = False
    """At the end, run the minimal world without the elements a precondition kept 3 times, the precondition
    bypassed (`Reduction.without_precondition_kept`): information for the reader, no verdict, so off by default
    (the plugin's `explain` stage simulates each such model's removal when the stages are asked for)."""


SETTING_NAMES: tuple[str, ...] = tuple(field.name for field in fields(ReductionSettings))


def validate(
    elements: Sequence[str],
    probe: Probe,
    given: ReductionSettings,
    *,
    geometry: Geometry | None,
    reference: Trace | None,
    executor: concurrent.futures.Executor | None,
    log: ProbeLog | str | os.PathLike[str] | None,
    on_progress: Callable[[ProgressEvent], None] | None,
) -> Settings:
    """Check every argument; raise ReductionError naming the argument, the value and what is allowed."""
    if not isinstance(given, ReductionSettings):
        raise ReductionError(expected("a ReductionSettings", given, "settings"))
    names = _elements(elements)
    if not callable(probe):
        raise ReductionError(expected("a callable probe(candidate, attempt) -> ProbeObservation", probe, "probe"))
    kept = _keep(given.keep, names)
    _check_inputs(geometry, reference)
    checks = _preconditions(given.preconditions)
    seconds = _max_seconds(given.max_seconds)
    _check_services(given.cache, executor, log, on_progress)
    max_probes = given.max_probes
    if max_probes == 0 and given.cache is None and log is None:  # nothing to decide from: it would do nothing
        raise ReductionError(expected("an integer >= 1 (0, no simulation at all, only goes with a log or a cache "
                                      "to reuse verdicts from)", max_probes, "max_probes"))
    return Settings(
        elements=names,
        keep=kept,
        probe=probe,
        geometry=geometry,
        reference=reference,
        partitioner=make_partitioner(given.partition),
        prioritizer=make_prioritizer(given.priority),
        n_partitions=_int("n_partitions", given.n_partitions, 2),
        granularity=_choice("granularity", given.granularity, GRANULARITIES),
        complement_order=_choice("complement_order", given.complement_order, COMPLEMENT_ORDERS),
        policy=make_policy(given.deflake, given.confidence),
        preconditions=checks,
        max_probes=None if max_probes is None else _int("max_probes", max_probes, 0),
        max_seconds=seconds,
        seed=_int("seed", given.seed, 0),
        cache=given.cache,
        executor=executor,
        log=log,
        failure_rate_runs=_int("failure_rate_runs", given.failure_rate_runs, 0),
        on_progress=on_progress,
        check_independence=_flag("check_independence", given.check_independence),
        workers=_workers(given.workers),
        first_cut=None if given.first_cut is None else _names_of("first_cut", given.first_cut, names),
        precondition_check=_flag("precondition_check", given.precondition_check),
    )


def _workers(workers: int | None) -> int:
    """How many probes a round keeps running at once on the executor: `workers` (an int >= 1), by default
    the number of CPUs (the executor's own worker count is not public)."""
    if workers is None:
        return os.cpu_count() or 2
    if not is_integral(workers) or int(workers) < 1:
        raise ReductionError(f"workers: expected None or an integer >= 1, got {workers!r}")
    return int(workers)


def _elements(elements: Sequence[str]) -> tuple[str, ...]:
    """The element names: a sequence of distinct, non-empty strings."""
    if isinstance(elements, (str, bytes)) or not isinstance(elements, Sequence):
        raise ReductionError(expected("a sequence of element names", elements, "elements"))
    names = tuple(elements)
    for name in names:
        if not isinstance(name, str) or not name:
            raise ReductionError(expected("non-empty str names", name, "elements"))
    duplicates = sorted({name for name in names if names.count(name) > 1}) if len(set(names)) != len(names) else []
    if duplicates:
        raise ReductionError(expected("distinct element names", names, "elements",
                                      got=f"{', '.join(duplicates)} more than once"))
    return names


def _names_of(field: str, given: Collection[str], names: tuple[str, ...]) -> frozenset[str]:
    """`given` as a set of element names (a collection, not a string, of names among `names`)."""
    if isinstance(given, str) or not isinstance(given, Collection):
        raise ReductionError(expected("a collection of element names, not a string", given, field))
    chosen = frozenset(given)
    unknown = sorted(chosen - set(names), key=str)
    if unknown:
        raise ReductionError(f"{field} names elements that are not in the world: {', '.join(map(str, unknown))}")
    return chosen


def _keep(keep: Collection[str], names: tuple[str, ...]) -> frozenset[str]:
    """The elements no candidate drops: a collection of names among `names`."""
    if isinstance(keep, str):
        raise ReductionError(expected("a collection of element names, not a string", keep, "keep"))
    kept = frozenset(keep)
    unknown = sorted(kept - set(names))
    if unknown:
        raise ReductionError(f"keep names elements that are not in the world: {', '.join(unknown)}")
    return kept


def _check_inputs(geometry: Geometry | None, reference: Trace | None) -> None:
    """What the partition and priority rules read: the world's geometry and the reference run's trace."""
    if geometry is not None and not (
        callable(getattr(geometry, "centroids", None)) and callable(getattr(geometry, "distances", None))
    ):
        raise ReductionError(expected("None or an object with centroids(names) and distances(points, names)",
                                      geometry, "geometry"))
    if reference is not None and not isinstance(reference, Trace):
        raise ReductionError(expected("a Trace or None", reference, "reference"))


def _preconditions(preconditions: Sequence[Precondition]) -> tuple[Precondition, ...]:
    checks = tuple(preconditions)
    for check in checks:
        if not callable(check):
            raise ReductionError(expected("callables check(candidate) -> str | None", check, "preconditions"))
    return checks


def _max_seconds(max_seconds: float | None) -> float | None:
    if max_seconds is None:
        return None
    if not is_real(max_seconds) or not max_seconds >= 0:  # `not >= 0` also refuses NaN
        raise ReductionError(expected("None or a number >= 0", max_seconds, "max_seconds"))
    return float(max_seconds)


def _check_services(
    cache: MutableMapping[Any, Any] | None,
    executor: concurrent.futures.Executor | None,
    log: ProbeLog | str | os.PathLike[str] | None,
    on_progress: Callable[[ProgressEvent], None] | None,
) -> None:
    """The optional helpers a reduction calls: its cache, executor, probe log and progress callback."""
    if cache is not None and not isinstance(cache, MutableMapping):
        raise ReductionError(expected("None or a MutableMapping", cache, "cache"))
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise ReductionError(expected("None or a concurrent.futures.Executor", executor, "executor"))
    if log is not None and not isinstance(log, (ProbeLog, str, os.PathLike)):
        raise ReductionError(expected("None, a path or a ProbeLog", log, "log"))
    if on_progress is not None and not callable(on_progress):
        raise ReductionError(expected("None or callable(ProgressEvent)", on_progress, "on_progress"))
