"""The values the reduction engine exchanges with its caller: outcomes, traces, observations, results.

Everything here is plain data (frozen dataclasses, numpy arrays, strings). The engine knows the elements
of a world only by their names; the geometry and the traces come from the caller.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.outcome import Outcome as Outcome  # re-exported: the engine's callers import it from here
from pytest_ddenv.reduce.rates import RateComparison

FloatArray = NDArray[np.float64]
Candidate = tuple[str, ...]
"""A sub-world: element names in the original order (kept elements included)."""


@dataclass(frozen=True, eq=False)
class Trace:
    """What the schemas need from one failing run, as plain numpy arrays in the world frame."""

    times: FloatArray
    """(T,) simulated seconds."""
    positions: FloatArray
    """(T, 3) robot position in the world frame."""
    yaw_rates: FloatArray
    """(T,) angular velocity about z (rad/s)."""
    failure_position: FloatArray | None = None
    """(3,) where the failure was detected, or None."""
    first_sensed: Mapping[str, float] = field(default_factory=dict)
    """Element name -> first time the robot's laser sensed it (absent = never sensed)."""
    touched: frozenset[str] = frozenset()
    """Elements the robot touched."""
    carried: FloatArray | None = None
    """(T, 3) the path of what the robot carries at the same times (an arm's target), or None: its points are
    trace points too for the distances of the schemas."""

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        count = times.shape[0]
        positions = np.asarray(self.positions, dtype=np.float64)
        if positions.size == 0 and count == 0:
            positions = np.zeros((0, 3))
        if positions.shape != (count, 3):
            raise ReductionError(
                f"Trace.positions must have shape (T, 3) = ({count}, 3) to match Trace.times, got {positions.shape}"
            )
        yaw_rates = np.asarray(self.yaw_rates, dtype=np.float64).reshape(-1)
        if yaw_rates.shape != (count,):
            raise ReductionError(
                f"Trace.yaw_rates must have shape (T,) = ({count},) to match Trace.times, got {yaw_rates.shape}"
            )
        failure_position = None
        if self.failure_position is not None:
            failure_position = np.asarray(self.failure_position, dtype=np.float64).reshape(-1)
            if failure_position.shape != (3,):
                raise ReductionError(
                    f"Trace.failure_position must be None or have shape (3,), got {failure_position.shape}"
                )
        carried = None if self.carried is None else np.asarray(self.carried, dtype=np.float64)
        if carried is not None and carried.shape != (count, 3):
            raise ReductionError(
                f"Trace.carried must be None or have shape (T, 3) = ({count}, 3) to match Trace.times, got "
                f"{carried.shape}")
        for name, value in (("times", times), ("positions", positions), ("yaw_rates", yaw_rates),
                            ("carried", carried)):
            if value is not None and not np.all(np.isfinite(value)):
                raise ReductionError(f"Trace.{name} contains NaN or infinite values")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "yaw_rates", yaw_rates)
        object.__setattr__(self, "failure_position", failure_position)
        object.__setattr__(self, "carried", carried)
        object.__setattr__(self, "first_sensed", {str(k): float(v) for k, v in dict(self.first_sensed).items()})
        object.__setattr__(self, "touched", frozenset(self.touched))

    @classmethod
    def empty(cls) -> Trace:
        """A trace without samples (T = 0), no failure position, nothing sensed."""
        return cls(times=np.zeros(0), positions=np.zeros((0, 3)), yaw_rates=np.zeros(0))

    def __len__(self) -> int:
        return int(self.times.shape[0])

    def to_json(self) -> dict[str, Any]:
        """The trace as JSON values (floats exactly: `json` writes the shortest text that reads back the same)."""
        return {"times": self.times.tolist(), "positions": self.positions.tolist(),
                "yaw_rates": self.yaw_rates.tolist(),
                "failure_position": None if self.failure_position is None else self.failure_position.tolist(),
                "first_sensed": dict(self.first_sensed), "touched": sorted(self.touched),
                "carried": None if self.carried is None else self.carried.tolist()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Trace:
        """The trace `to_json` wrote; ReductionError when `data` is not one."""
        try:
            positions = np.asarray(data["positions"], dtype=np.float64).reshape(-1, 3)
            carried = data.get("carried")
            position = data.get("failure_position")
            sensed = dict(data.get("first_sensed", {}))
            return cls(times=np.asarray(data["times"], dtype=np.float64), positions=positions,
                       yaw_rates=np.asarray(data["yaw_rates"], dtype=np.float64),
                       failure_position=None if position is None else np.asarray(position, dtype=np.float64),
                       first_sensed={str(name): float(time) for name, time in sensed.items()},
                       touched=frozenset(str(name) for name in data.get("touched", ())),
                       carried=None if carried is None else np.asarray(carried, dtype=np.float64).reshape(-1, 3))
        except (KeyError, TypeError, ValueError) as error:
            raise ReductionError(f"not a trace: {error}") from error


@dataclass(frozen=True)
class ProbeObservation:
    """What a probe returns for one simulation of one candidate (a controller's view of the robot is
    `pytest_ddenv.Observation`, the simulation's)."""

    outcome: Outcome
    trace: Trace | None = None
    """The run's trace, when the outcome is FAIL and it is available."""
    signature: Mapping[str, Any] | None = None
    """JSON-able failure signature, logged verbatim."""
    seed: int | None = None
    sim_time: float = 0.0
    wall_time: float = 0.0
    detail: str = ""
    """Free text, e.g. an error message."""


@runtime_checkable
class Geometry(Protocol):
    """Where the elements are, supplied by the world model (one world frame)."""

    def centroids(self, names: Sequence[str]) -> FloatArray:
        """(E, 3) a representative point of each named element."""
        ...

    def distances(self, points: FloatArray, names: Sequence[str]) -> FloatArray:
        """(N, E) distance from each point to each element's real surface (0 inside)."""
        ...


Probe = Callable[[Candidate, int], ProbeObservation]
"""probe(candidate, attempt) -> ProbeObservation. attempt is 0, 1, 2, ... per candidate (a distinct seed each)."""

Precondition = Callable[[Candidate], "str | None"]
"""precondition(candidate) -> None to allow probing it, or the reason to skip it (treated as not f)."""


@dataclass(frozen=True)
class Decision:
    """The verdict on one candidate: does it reproduce f (after deflaking)?"""

    reproduces: bool
    fails: int
    """How many of the runs gave f."""
    runs: int
    """How many runs the verdict is based on (the attempts 0 .. runs-1)."""
    trace: Trace | None = field(default=None, compare=False, repr=False)
    """The trace of the first f run, when there was one (logged with an acceptance: a resumed reduction's
    schemas read the same trace as the run that accepted it)."""
    errors: int = field(default=0, compare=False)
    """How many of the runs were ERROR (no outcome of the world: a crash, a timeout)."""
    errored: bool = False
    """A rejection that rests on ERROR runs: without them the deflake rule would not have rejected. It is
    treated as "not f" for the decisions of this reduction, but it is no verdict: it is never stored in the
    cache or read back from a log (a resumed reduction tries the candidate again), and a reduction whose
    1-minimality rests on one is not reported 1-minimal."""


class ProbeCancelled(Exception):
    """Raised by a probe whose simulation its caller stopped (e.g. at the max_seconds deadline): not an
    outcome. The engine records nothing for it and ends the reduction as out of budget."""

    def __init__(self, reason: str = "budget: max_seconds") -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class ProgressEvent:
    """Reported to `on_progress` as the reduction goes."""

    kind: str
    """"start", "round", "probe", "step" (a smaller world was adopted), "verify" or "end"."""
    size: int
    """Current number of elements (kept ones included)."""
    probes: int
    """Probes decided so far (simulations whose result was used; a resumed log's included)."""
    granularity: int
    elapsed: float
    """Wall seconds since the reduction started."""
    candidate: Candidate | None = None
    outcome: Outcome | None = None


@dataclass(frozen=True)
class FirstCutResult:
    """A first cut tried: `original` elements, `kept` of them in its candidate, whether it reproduced f
    (`holds`: the rounds started from it) and the simulations its trial started."""

    original: int
    kept: int
    holds: bool
    simulations: int

    def describe(self) -> str:
        runs = f"{self.simulations} simulation{'' if self.simulations == 1 else 's'}"
        if self.holds:
            return f"first cut by reach: {self.original} -> {self.kept} models in {runs}"
        return (f"first cut by reach: {self.original} -> {self.kept} models did not reproduce the failure "
                f"({runs}); reduced from the whole world")

    def to_json(self) -> dict[str, int | bool]:
        return {"original": self.original, "kept": self.kept, "holds": self.holds, "simulations": self.simulations}


@dataclass(frozen=True)
class Reduction:
    """The result of `reduce`: the minimal world and how it was reached."""

    original: Candidate
    minimal: Candidate
    """The smallest failing world found (kept elements included), original order."""
    kept: Candidate
    """Elements that were never reducible (`keep`)."""
    probes: int
    """Probes decided: simulations whose result the reduction used (first runs, deflake re-runs and the
    calibration runs of deflake="auto"; failure-rate runs excluded). A resumed reduction counts the probes of
    the log it resumed (`resumed_probes` of them) too, so this is the whole history."""
    cache_hits: int
    """Candidates whose verdict came from the cache (or a resumed log) instead of a simulation."""
    skipped: int
    """Distinct candidates a precondition skipped without simulating them."""
    errors: int
    """Simulations of this call whose outcome was ERROR (the probe raised or reported an error)."""
    steps: tuple[tuple[int, int], ...]
    """(probes so far, size) at the start and after each adopted smaller world."""
    one_minimal: bool
    """True when every single reducible element of `minimal` was shown necessary (see docs/algorithm.md)."""
    incomplete_reason: str | None
    """None, "budget: max_probes", "budget: max_seconds", "interrupted", "world-independent" (see
    `independent`), or "not verified: N candidates
    errored" (the minimal world is 1-minimal only if those N single removals, rejected on ERROR runs alone,
    do not reproduce f; a resumed reduction tries them again)."""
    failure_rate: tuple[int, int]
    """(fails, runs) of `minimal` on fresh attempts (after those it was accepted on): the rate comparison's
    runs (at most `failure_rate_runs`)."""
    wall_time: float
    partition: str
    priority: str
    granularity: str
    deflake: int | str
    """The deflake policy: re-runs, "adaptive", or "auto:K-of-N" (calibrated: f on K of at most N runs)."""
    seed: int
    calibration: tuple[int, int] | None = None
    """deflake="auto": (fails, runs) of the original world's calibration runs (also counted in `probes`)."""
    simulations: int = 0
    """Simulations this call of `reduce` started, whatever became of them: decided probes, calibration and
    failure-rate runs, and speculative or prefetched runs whose result was not needed. Never more than
    `max_probes`. (Earlier runs of a resumed log: `resumed_probes`.)"""
    resumed_probes: int = 0
    """Of `probes`, those read from the resumed log (0 for a fresh reduction)."""
    errored: int = 0
    """Distinct candidates rejected on ERROR runs alone (see `Decision.errored`), retried once at the end."""
    notes: tuple[str, ...] = ()
    """What the reduction wants its reader to know (a torn log line cut off, a candidate that errored)."""
    rate_check: RateComparison | None = None
    """The minimal world's failure rate on fresh runs compared with the original's (rates.py): "holds",
    "below" (significantly lower, after `rate_backoffs` back-offs), or "continue" (the budget stopped the
    comparison). None when nothing was removed or `failure_rate_runs` is 0."""
    rate_backoffs: int = 0
    """How many times the reduction backed off from a minimal world whose rate was significantly lower."""
    precondition_kept: tuple[tuple[str, str], ...] = ()
    """(element, reason): elements of `minimal` whose removal a precondition refused; they were not shown
    needed for the failure, only for the scenario to be valid."""
    without_precondition_kept: tuple[int, int] | None = None
    """(fails, runs) of `minimal` without the `precondition_kept` elements (preconditions bypassed, a few
    runs): information, not part of the verdict."""
    independent: bool = False
    """`check_independence`: the world without its reducible elements (but those the preconditions need)
    reproduced f, so the failure does not depend on them and nothing was reduced (`incomplete_reason`
    "world-independent")."""
    first_cut: FirstCutResult | None = None
    """The first cut (`ReductionSettings.first_cut`) when it was tried."""

    @property
    def original_failure_rate(self) -> tuple[int, int] | None:
        """(fails, runs) of the original world's fresh runs: the rate comparison's (which counts the
        calibration's; it may need none, `RateComparison.skipped`), else the calibration's."""
        if self.rate_check is not None and self.rate_check.original.runs:
            return (self.rate_check.original.fails, self.rate_check.original.runs)
        return self.calibration

    @property
    def needed(self) -> Candidate:
        """The elements of `minimal` shown needed for the failure (not kept by `keep` or a precondition)."""
        other = set(self.kept) | {name for name, _ in self.precondition_kept}
        return tuple(name for name in self.minimal if name not in other)

    @property
    def original_size(self) -> int:
        return len(self.original)

    @property
    def minimal_size(self) -> int:
        return len(self.minimal)

    @property
    def removed(self) -> Candidate:
        """The elements the reduction removed, original order."""
        keep = set(self.minimal)
        return tuple(name for name in self.original if name not in keep)


class ReductionInterrupted(ReductionError, KeyboardInterrupt):
    """Raised by `reduce` on KeyboardInterrupt, after flushing the log.

    It is a KeyboardInterrupt (so ``except KeyboardInterrupt`` and pytest's interrupt handling still see a
    Ctrl-C) and a ReductionError; `.reduction` is the best world found so far, with
    ``incomplete_reason == "interrupted"`` and ``one_minimal == False``.
    """

    outcome: object | None
    """What the caller made of the interrupted reduction before it re-raised this (the driver's
    `ReductionOutcome`, the files written: read it with the driver's `interrupted_outcome`); None from `reduce`."""

    def __init__(self, reduction: Reduction) -> None:
        self.reduction = reduction
        self.outcome = None
        super().__init__(
            f"reduction interrupted after {reduction.probes} probes; best world so far has "
            f"{len(reduction.minimal)} of {len(reduction.original)} elements"
        )
