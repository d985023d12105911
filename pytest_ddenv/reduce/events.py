"""The events of a run log (`runs.jsonl`): one frozen dataclass per kind, one writer (`encode`) and one reader
(`decode`). This is the only module that knows how an event is spelt on disk.

A line is one JSON object whose ``"event"`` key names its kind (`KINDS`); the other keys are the fields of
its class, with ``stage`` (the stage after the model-level reduction that wrote it, absent for the
model-level reduction) and ``elapsed`` (seconds since the reduction started) on every kind. A field whose
value is None is left out of the line, except those in its class's `NULLS_WRITTEN`. The schema version,
`SCHEMA_VERSION`, is written in the ``format`` field of the log's first event (`Problem`, `Start`); a log of
a later version is refused rather than misread.

`decode` is defensive: a line that is not a JSON object, is nested deeper than `MAX_JSON_NESTING`, names no
kind or an unknown one, lacks a field its class requires or holds a field of the wrong type gives an
`Unreadable` (what is wrong, for the caller's note), never a half-read event. Fields of a known kind that
this version does not know are ignored (a later version may add some).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Final, TypeAlias

import numpy as np

from pytest_ddenv.reduce.records import json_value
from pytest_ddenv.reduce.types import Outcome

SCHEMA_VERSION: Final = 1
"""The version of the events' shape; written as ``format`` in `Problem` and `Start`."""

Names: TypeAlias = tuple[str, ...]
Count: TypeAlias = int
"""An integer >= 0."""
FailsOfRuns: TypeAlias = tuple[Count, Count]
OutcomeName: TypeAlias = str
"""An `Outcome`'s value."""
JsonObject: TypeAlias = Mapping[str, Any]
_Check = tuple[str, Callable[[Any], bool], Callable[[Any], Any]]


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _number(value: Any) -> bool:
    """A finite number, or one that `jsonable` wrote as text ("nan", "inf", "-inf")."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)) or (
        value in _NOT_FINITE)


_NOT_FINITE = frozenset({"nan", "inf", "-inf"})


def _names(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(item, str) for item in value)


def _point(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 5 and all(_number(item) for item in value)


def _same(value: Any) -> Any:
    return value


_CHECKS: Mapping[str, _Check] = {
    "Names": ("a list of model names", _names, tuple),
    "tuple[Names, ...]": ("a list of lists of names", lambda value: isinstance(value, list) and all(map(_names, value)),
                   lambda value: tuple(tuple(item) for item in value)),
    "Count": ("an integer >= 0", _count, _same),
    "int": ("an integer", _integer, _same),
    "tuple[Count, ...]": ("a list of integers >= 0", lambda value: isinstance(value, list) and all(map(_count, value)),
                          tuple),
    "OutcomeName": (f"one of {', '.join(outcome.value for outcome in Outcome)}",
                    lambda value: value in {outcome.value for outcome in Outcome}, _same),
    "str": ("a string", lambda value: isinstance(value, str), _same),
    "str | int": ("a string or an integer", lambda value: isinstance(value, str) or _integer(value), _same),
    "bool": ("true or false", lambda value: isinstance(value, bool), _same),
    "float": ("a number", _number, float),
    "FailsOfRuns": ("[fails, runs]", lambda value: isinstance(value, list) and len(value) == 2
                            and all(map(_count, value)), tuple),
    "tuple[tuple[float, ...], ...]": ("a list of [distance, time, x, y, yaw]", lambda value: isinstance(value, list)
                                      and all(_point(item) for item in value),
                                      lambda value: tuple(tuple(map(float, point)) for point in value)),
    "JsonObject": ("an object", lambda value: isinstance(value, dict), _same),
    "Any": ("a JSON value", lambda value: True, _same),
}
"""How a field is read, by its annotation (without `` | None``, which allows null)."""


def _check(annotation: str) -> _Check:
    """How a field with this annotation is read."""
    if annotation.endswith(" | None"):
        what, valid, convert = _CHECKS[annotation.removesuffix(" | None")]
        return (f"{what} or null", lambda value: value is None or valid(value),
                lambda value: None if value is None else convert(value))
    return _CHECKS[annotation]


@dataclass(frozen=True, kw_only=True)
class Event:
    """What every event has: the stage that wrote it (None: the model-level reduction) and the seconds since
    its reduction started (None for the driver's events)."""

    NAME: ClassVar[str] = ""
    """The name a line gives this kind (its ``"event"``), given as ``class Step(Adopted, name="step")``."""
    NULLS_WRITTEN: ClassVar[frozenset[str]] = frozenset()
    """The fields written as null when None (the others are left out)."""
    stage: str | None = None
    elapsed: float | None = None

    def __init_subclass__(cls, name: str = "", **options: Any) -> None:
        super().__init_subclass__(**options)
        if name:
            cls.NAME = name


@dataclass(frozen=True, kw_only=True)
class Problem(Event, name="problem"):
    """The first event of an artifacts folder's log: which problem it belongs to (`driver.problem`)."""

    NULLS_WRITTEN = frozenset({"reference"})
    format: Count = SCHEMA_VERSION
    fingerprint: str
    test: str = ""
    parts: JsonObject
    code: Any = None
    reference: JsonObject | None = None


@dataclass(frozen=True, kw_only=True)
class Session(Event, name="session"):
    """A run of the driver on this log began (a resumed reduction adds one per run)."""

    pid: int
    time: str


@dataclass(frozen=True, kw_only=True)
class Usage(Event, name="usage"):
    """The simulations and worker CPU seconds of this run of the driver so far (`final`: at its end)."""

    simulations: Count = 0
    cpu_seconds: float = 0.0
    final: bool = False


@dataclass(frozen=True, kw_only=True)
class Start(Event, name="start"):
    """A reduction began (`resumed`: from this log's verdicts) with these elements and settings."""

    NULLS_WRITTEN = frozenset({"seed", "max_probes", "max_seconds"})
    format: Count = SCHEMA_VERSION
    resumed: bool = False
    elements: Names = ()
    keep: Names = ()
    partition: str | None = None
    priority: str | None = None
    n_partitions: Count | None = None
    granularity: str | None = None
    complement_order: str | None = None
    deflake: str | int | None = None
    seed: int | None = None
    max_probes: Count | None = None
    max_seconds: float | None = None
    failure_rate_runs: Count | None = None
    reference: bool | None = None


@dataclass(frozen=True, kw_only=True)
class Calibration(Event, name="calibration"):
    """deflake="auto": the original world's failure rate and the rule chosen from it."""

    fails: Count
    runs: Count
    rule: str | int | None = None


@dataclass(frozen=True, kw_only=True)
class Round(Event, name="round"):
    """A round of the model-level reduction: its parts and the order it tries them in."""

    index: Count
    granularity: Count
    size: Count
    parts: tuple[Names, ...] = ()
    removal_order: tuple[Count, ...] = ()
    subsets: bool | None = None


@dataclass(frozen=True, kw_only=True)
class Probe(Event, name="probe"):
    """One simulation whose result was used. `purpose`: "reduce" (deciding a candidate), "calibration",
    "failure-rate", "independence", or the driver's own runs ("confirm", "picture"); `attempt` picks the
    seed."""

    NULLS_WRITTEN = frozenset({"seed", "signature"})
    purpose: str = "reduce"
    kind: str | None = None
    candidate: Names
    size: Count | None = None
    attempt: Count
    seed: Count | None = None
    outcome: OutcomeName
    signature: JsonObject | None = None
    sim_time: float | None = None
    wall_time: float | None = None
    detail: Any = None

    @property
    def result(self) -> Outcome:
        """`outcome` as an `Outcome`."""
        return Outcome(self.outcome)


@dataclass(frozen=True, kw_only=True)
class EngineRun(Event, name="engine-run"):
    """One run of the minimal or the original world in another physics engine than the reduction's (or in its
    own, for a world it made no fresh runs of), after the reduction (`--ddenv-confirm-engines`). `engine` is
    its name and version ("mujoco 3.3.0"): a resumed reduction reuses the run only in the same engine of the
    same version."""

    NULLS_WRITTEN = frozenset({"seed", "signature"})
    engine: str
    world: str
    """"minimal" or "original"."""
    candidate: Names
    attempt: Count
    seed: Count | None = None
    outcome: OutcomeName
    signature: JsonObject | None = None
    sim_time: float | None = None
    wall_time: float | None = None

    @property
    def result(self) -> Outcome:
        """`outcome` as an `Outcome`."""
        return Outcome(self.outcome)


@dataclass(frozen=True, kw_only=True)
class OfCandidate(Event):
    """An event about one candidate world: its elements in original order, their number, and the kind of trial
    that made it (the engine's)."""

    kind: str | None = None
    candidate: Names
    size: Count | None = None


@dataclass(frozen=True, kw_only=True)
class Decided(OfCandidate):
    """A verdict on a candidate (the kinds below): does it reproduce the failure, on how many runs."""

    reproduces: bool
    fails: Count
    runs: Count
    errors: Count | None = None
    """ERROR runs among those the verdict was decided on."""
    errored: bool | None = None
    """The verdict rests on ERROR runs: not a verdict a resumed reduction reuses."""


@dataclass(frozen=True, kw_only=True)
class Accept(Decided, name="accept"):
    """The candidate reproduces the failure."""

    trace: JsonObject | None = None
    """The trace of its first failing run (`Trace.to_json`): the schemas of the rounds after it read it, so a
    resumed reduction that accepts it from the log orders its rounds as the run that accepted it did."""


class Reject(Decided, name="reject"):
    """It does not."""


class Errored(Decided, name="errored"):
    """Rejected only because of ERROR runs (decided again by a resumed reduction)."""


class CacheHit(Decided, name="cache-hit"):
    """A verdict known already, looked up again."""


class RateBelow(Decided, name="rate-below"):
    """An accepted world rejected after all: it failed significantly less often than the original."""


@dataclass(frozen=True, kw_only=True)
class Skip(OfCandidate, name="skip"):
    """A candidate a precondition refused, never simulated."""

    reason: str = ""


@dataclass(frozen=True, kw_only=True)
class Adopted(OfCandidate):
    """A world the reduction went on from, after `probes` decided probes (the kinds below)."""

    probes: Count | None = None


class Step(Adopted, name="step"):
    """A smaller world adopted."""


class BackOff(Adopted, name="back-off"):
    """An earlier, larger world gone back to (after `RateBelow`)."""


@dataclass(frozen=True, kw_only=True)
class Measured(OfCandidate):
    """How often a candidate failed the same way on fresh runs (the kinds below)."""

    fails: Count
    runs: Count


class FailureRate(Measured, name="failure-rate"):
    """The failure rate of the minimal world."""


class PreconditionCheck(Measured, name="precondition-check"):
    """The minimal world without the elements only a precondition kept: how often it still fails."""


@dataclass(frozen=True, kw_only=True)
class RateCheck(OfCandidate, name="rate-check"):
    """The comparison of a reduced world's failure rate with the original's."""

    original: FailsOfRuns
    reduced: FailsOfRuns
    p_value: float
    decision: str


@dataclass(frozen=True, kw_only=True)
class FailurePath(Event, name="path"):
    """The time stage's start points along the failing run and the time of its failure."""

    failure_time: float
    points: tuple[tuple[float, ...], ...]


@dataclass(frozen=True, kw_only=True)
class FirstCut(Event, name="first-cut"):
    """The first cut by reach (driver/reach.py): `original` models, `kept` of them within reach; `decision`
    "holds" (one trial reproduced f: the rounds start from the kept world), "does-not-hold" (they start from
    the whole world) or "skipped" (not tried: `reason`); `simulations` the trial's."""

    original: Count
    kept: Count
    decision: str
    simulations: Count = 0
    reason: str = ""


@dataclass(frozen=True, kw_only=True)
class End(Event, name="end"):
    """A reduction ended: its result, as counted."""

    NULLS_WRITTEN = frozenset({"incomplete_reason", "rate_check"})
    minimal: Names
    size: Count
    original_size: Count
    probes: Count
    """Decided probes, the resumed log's included (`Reduction.probes`)."""
    simulations: Count
    """Simulations this call started (`Reduction.simulations`)."""
    resumed_probes: Count
    cache_hits: Count
    skipped: Count
    """Candidates a precondition refused."""
    errors: Count
    errored: Count
    """Candidates rejected only because of ERROR runs."""
    steps: Any = None
    """[probes, size] of the start and of each adopted world."""
    one_minimal: bool
    incomplete_reason: str | None = None
    failure_rate: Any = None
    """[fails, runs] of the minimal world."""
    rate_check: str | None = None
    rate_backoffs: Count
    wall_time: float


KINDS: Mapping[str, type[Event]] = {kind.NAME: kind for kind in (
    Problem, Session, Usage, Start, Round, Probe, Accept, Reject, Errored, CacheHit, RateBelow, Skip, Step,
    BackOff, Calibration, FailureRate, PreconditionCheck, RateCheck, FailurePath, EngineRun, FirstCut, End)}
"""Every kind of event, by the name a line spells it with."""
VERDICTS: tuple[type[Decided], ...] = (Accept, Reject, CacheHit, RateBelow)
"""The decisions a resumed reduction reuses (unless `errored`)."""


@dataclass(frozen=True)
class Unreadable:
    """A line that holds no event this version can read, and why."""

    problem: str


_LAST = ("elapsed", "stage")
"""The fields every event has, written after its own (in this order)."""


def _written(event: Event) -> list[dataclasses.Field[Any]]:
    """The fields of an event in the order a line holds them: its own, then `_LAST`."""
    return sorted(dataclasses.fields(event), key=lambda item: _LAST.index(item.name) + 1 if item.name in _LAST else 0)


def jsonable(value: Any) -> Any:
    """A JSON-compatible copy of `value` (numpy scalars and arrays, tuples, sets, enums, paths ...)."""
    if isinstance(value, Outcome):
        return value.value
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else str(number)
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Mapping):
        return {str(key): jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(item) for item in value]
    if isinstance(value, (set, frozenset)):
        return sorted((jsonable(item) for item in value), key=str)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return repr(value)


def to_json(event: Event) -> dict[str, Any]:
    """The JSON object of an event (what its line holds, before numpy values and tuples are made JSON)."""
    record: dict[str, Any] = {"event": event.NAME}
    for item in _written(event):
        value = getattr(event, item.name)
        if value is not None or item.name in event.NULLS_WRITTEN:
            record[item.name] = value
    return record


def encode(event: Event) -> str:
    """The line of `event` (without its newline): the one writer of run-log lines."""
    return json.dumps(jsonable(to_json(event)), allow_nan=False)


def from_json(record: Mapping[str, Any]) -> Event | Unreadable:
    """The event a JSON object holds, or why it holds none."""
    kind = record.get("event")
    if not isinstance(kind, str):
        return Unreadable("no 'event' name")
    cls = KINDS.get(kind)
    if cls is None:
        return Unreadable(f"an unknown event {kind!r}")
    values: dict[str, Any] = {}
    for item in dataclasses.fields(cls):
        if item.name not in record:
            if item.default is dataclasses.MISSING:
                return Unreadable(f"a {kind!r} record without '{item.name}'")
            continue
        what, valid, convert = _check(str(item.type))
        value = record[item.name]
        if not valid(value):
            return Unreadable(f"'{item.name}' of a {kind!r} record is not {what}")
        values[item.name] = convert(value)
    return cls(**values)


def decode(line: str) -> Event | Unreadable | None:
    """The event one line of a run log holds (None: a blank line): the one reader of run-log lines."""
    if not line.strip():
        return None
    try:
        record = json_value(line)
    except ValueError:  # invalid JSON, or nested too deep
        return Unreadable("not a JSON object (or nested too deep)")
    if not isinstance(record, dict):
        return Unreadable("not a JSON object (or nested too deep)")
    return from_json(record)


def later_format(event: Event) -> int | None:
    """The schema version of `event` (a log's first) when it is later than the one this version reads."""
    return event.format if isinstance(event, (Problem, Start)) and event.format > SCHEMA_VERSION else None
