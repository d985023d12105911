"""The bridge between a scenario test and the reduction engine.

A probe runs the test (or a bare simulation) on a candidate sub-world and classifies what it raised against
the original failure: same failure, other failure, pass, or error. No pytest import: the plugin and the
`ddenv` command both build their probes here.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.reduce import Observation, Outcome, Trace
from pytest_ddenv.robot_world import RobotFailure
from pytest_ddenv.world import World

if TYPE_CHECKING:
    from pytest_ddenv.oracle import FailureSignature
    from pytest_ddenv.reduce.types import Candidate, Precondition, Probe
    from pytest_ddenv.sim import Run

RunTest = Callable[[World, int], "tuple[BaseException | None, Run | None]"]
"""run_test(world, attempt) -> (what the test raised or None, the last Run it made or None)."""


@dataclass(frozen=True)
class FailureReference:
    """The original failure a probe must reproduce.

    A predicate failure (`RobotFailure`) is matched by its signature (same predicate, failure position within
    tolerance); any other exception by its type and the line of the test that raised it.
    """

    exception_type: str
    location: str
    signature: FailureSignature | None = None

    def describe(self) -> str:
        if self.signature is not None:
            return f"{self.signature.predicate} at t={self.signature.time:.1f} s"
        return f"{self.exception_type} at {self.location}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "exception_type": self.exception_type,
            "location": self.location,
            "signature": None if self.signature is None else self.signature.to_dict(),
        }


def reference_from(error: BaseException, test_file: str | Path | None) -> FailureReference:
    signature = error.signature if isinstance(error, RobotFailure) else None
    return FailureReference(type(error).__qualname__, raise_location(error, test_file), signature)


def raise_location(error: BaseException, test_file: str | Path | None) -> str:
    """file:line of the deepest frame of the traceback inside the test file (or the deepest frame at all)."""
    frames = traceback.extract_tb(error.__traceback__)
    if not frames:
        return "?"
    inside = [f for f in frames if test_file is not None and Path(f.filename) == Path(test_file)]
    frame = (inside or frames)[-1]
    return f"{Path(frame.filename).name}:{frame.lineno}"


def classify_error(
    error: BaseException | None,
    reference: FailureReference,
    tolerance: float,
    test_file: str | Path | None,
) -> Outcome:
    """Compare what a probe raised with the original failure."""
    from pytest_ddenv.oracle import classify

    if error is None:
        return Outcome.PASS
    if isinstance(error, RobotFailure):
        if reference.signature is None:
            return Outcome.OTHER
        return classify(error.run, reference.signature, tolerance)
    if isinstance(error, DdenvError):
        return Outcome.ERROR  # the candidate world cannot be simulated as given (e.g. nothing under the start)
    if reference.signature is None and type(error).__qualname__ == reference.exception_type:
        same_line = raise_location(error, test_file) == reference.location
        return Outcome.FAIL if same_line else Outcome.OTHER
    return Outcome.OTHER


def trace_of(run: Run) -> Trace:
    """What the reduction schemas need from a run."""
    failure_position = None if run.failure is None else np.asarray(run.failure.pose[:3], dtype=float)
    touched = frozenset(run.first_touch)
    return Trace(
        times=run.times,
        positions=run.positions,
        yaw_rates=run.velocities[:, 5] if len(run.velocities) else np.zeros(0),
        failure_position=failure_position,
        first_sensed=dict(run.first_sensed),
        touched=touched,
    )


def make_probe(
    world: World,
    run_test: RunTest,
    reference: FailureReference,
    *,
    tolerance: float,
    test_file: str | Path | None = None,
) -> Probe:
    """A probe for the engine: run the test on `world.select(candidate)` and classify the result."""

    def probe(candidate: Candidate, attempt: int) -> Observation:
        started = time.perf_counter()
        error, run = run_test(world.select(candidate), attempt)
        outcome = classify_error(error, reference, tolerance, test_file)
        signature: Mapping[str, Any] | None = None
        if isinstance(error, RobotFailure):
            signature = error.signature.to_dict()
        elif error is not None:
            signature = {"exception": type(error).__qualname__, "location": raise_location(error, test_file)}
        return Observation(
            outcome=outcome,
            trace=trace_of(run) if run is not None and outcome is Outcome.FAIL else None,
            signature=signature,
            seed=None if run is None else int(run.seed),
            sim_time=0.0 if run is None else float(run.sim_time),
            wall_time=time.perf_counter() - started,
            detail="" if error is None or outcome is Outcome.FAIL else f"{type(error).__name__}: {error}"[:300],
        )

    return probe


def start_support(world: World) -> str | None:
    """The model the robot's start pose rests on: the highest one under the start point (None: the ground)."""
    if world.scenario is None:
        return None
    start = world.scenario.start
    best: tuple[float, str] | None = None
    for name in world.names:
        low, high = world.bounds(name)
        if not (low[0] <= start.x <= high[0] and low[1] <= start.y <= high[1]):
            continue
        if world.scenario.start_z_given and high[2] > start.z + 0.05:
            continue
        top = float(world.distances(np.array([[start.x, start.y, high[2] + 1e-6]]), [name])[0, 0])
        if top > 0.05:  # the bounds contain the point but the shape itself is not under it
            continue
        if best is None or high[2] > best[0]:
            best = (float(high[2]), name)
    return None if best is None else best[1]


def keeps_start_support(world: World) -> Precondition:
    """A precondition: never remove the model under the robot's start (the scenario would change)."""
    support = start_support(world)

    def precondition(candidate: Candidate) -> str | None:
        if support is not None and support not in candidate:
            return f"removes '{support}', the model under the robot's start"
        return None

    return precondition
