"""The bridge between a scenario test and the reduction engine.

A probe runs the test on a candidate sub-world (in a worker, or in this process) and classifies what it
raised against the original failure: same failure, other failure, pass, or error. What crosses from the
worker is plain data (`ProbeResult`: an `ErrorInfo` and the last `Run`), never the user's exception
object, so unpicklable exceptions and user classes travel fine. No pytest import.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv import defaults
from pytest_ddenv.errors import raised_by_ddenv
from pytest_ddenv.oracle.verdict import ErrorInfo, FailureReference, classify_result
from pytest_ddenv.reduce import Outcome, ProbeObservation, Trace
from pytest_ddenv.scenario.robot_world import RobotFailure
from pytest_ddenv.world.model import World

if TYPE_CHECKING:
    from pytest_ddenv.oracle.verdict import OtherReason, SameFailureRule
    from pytest_ddenv.reduce.types import Candidate, Precondition, Probe
    from pytest_ddenv.sim import Run

DETAIL_LIMIT = 2000
"""Characters of an error's text kept in a probe's log line (the full traceback is in the first one)."""


@dataclass(frozen=True)
class ProbeResult:
    """One run of the test: what it raised (None: it passed) and the last `Run` it made (None: no run)."""

    error: ErrorInfo | None
    run: Run | None


def describe_error(error: BaseException, test_file: str | Path | None, *, phase: str = "call") -> ErrorInfo:
    """`error` as plain data (see `ErrorInfo`)."""
    return ErrorInfo(
        type_name=type(error).__qualname__,
        message=str(error)[:DETAIL_LIMIT],
        location=raise_location(error, test_file),
        traceback=user_traceback(error)[-20 * DETAIL_LIMIT:],
        signature=error.signature if isinstance(error, RobotFailure) else None,
        ddenv_error=raised_by_ddenv(error),
        phase=phase,
    )


_MACHINERY = ("/_pytest/", "/pluggy/")
"""Frames of pytest's own call machinery: left out of a probe's traceback (pytest's reports omit them too)."""


def user_traceback(error: BaseException) -> str:
    """`error`'s traceback without the frames of pytest's and pluggy's call machinery."""
    shown = traceback.TracebackException.from_exception(error)
    frames = [frame for frame in shown.stack if not any(part in frame.filename for part in _MACHINERY)]
    if frames:
        shown.stack = traceback.StackSummary.from_list(frames)
    return "".join(shown.format())


def raise_location(error: BaseException, test_file: str | Path | None) -> str:
    """file:line of the deepest frame of the traceback inside the test file (or the deepest frame at all)."""
    frames = traceback.extract_tb(error.__traceback__)
    if not frames:
        return "?"
    inside = [f for f in frames if test_file is not None and Path(f.filename) == Path(test_file)]
    frame = (inside or frames)[-1]
    return f"{Path(frame.filename).name}:{frame.lineno}"


def check_rule(reference: FailureReference, rule: SameFailureRule) -> None:
    """`SameFailureError` unless `rule` says the reference failure is the same as itself (a user's function that
    cannot be called, raises, or says no), before any simulation."""
    from pytest_ddenv.oracle.verdict import SameFailureError

    if reference.signature is not None and not rule.same(reference.signature, reference.signature):
        raise SameFailureError(f"the same-failure rule ({rule.describe(reference.signature)}) says the failure "
                               f"being reduced ({reference.describe()}) is not the same as itself")


def why_not_reproduced(found: Mapping[str, Any] | None, reference: FailureReference,
                       rule: SameFailureRule) -> OtherReason | None:
    """Why a probe whose failure the run log records as `found` (`signature_record`: a predicate's signature,
    {"exception", "location"}, or None when the test passed) is not the reference failure; None when it is,
    or when `found` cannot be read."""
    from pytest_ddenv.oracle.predicates import FailureSignature
    from pytest_ddenv.oracle.verdict import OtherReason, why_other

    expected = reference.describe()
    if found is None:
        return OtherReason("the test passed", "the test passed (no failure)")
    if "predicate" in found:
        try:
            signature = FailureSignature.from_dict(found)
        except (KeyError, TypeError, ValueError, IndexError):
            return None
        if reference.signature is not None:
            return why_other(signature, reference.signature, rule) if len(signature.pose) >= 3 else None
        return OtherReason(f"the '{signature.predicate}' predicate fired instead of {expected}",
                           f"the '{signature.predicate}' predicate fired instead")
    if "exception" in found:
        raised = f"{found['exception']} at {found.get('location', '?')}"
        if reference.signature is None and raised == expected:
            return None
        return OtherReason(f"the test raised {raised} (the reference: {expected})", f"the test raised {raised}",
                           f"the reference: {expected}")
    return None


def signature_record(error: ErrorInfo | None) -> Mapping[str, Any] | None:
    """What the run log says about a probe's failure (JSON-able)."""
    if error is None:
        return None
    if error.signature is not None:
        return error.signature.to_dict()
    return {"exception": error.type_name, "location": error.location}


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
        carried=run.target_path if run.target_path is not None and len(run.target_path) == len(run.times) else None,
    )


ProbeCall = Callable[[World, int], ProbeResult]
"""call(world, attempt) -> ProbeResult: a pool's `call`, or a handler in this process."""


def make_probe(world: World, call: ProbeCall, reference: FailureReference, *,
               tolerance: float = defaults.TOLERANCE, rule: SameFailureRule | None = None,
               build: Callable[[Candidate], World] | None = None) -> Probe:
    """A probe for the engine: run the test on `world.select(candidate)` (or on `build(candidate)`: the
    stages after the model-level reduction reduce shapes and simplifications, not models) and classify the
    result by `rule` (default: the default rule with `tolerance`), here in the calling process.

    What `call` itself raises (a worker that died twice, a test that cannot start in a worker) is an ERROR
    observation whose detail is the exception's text, never a verdict.
    """

    def probe(candidate: Candidate, attempt: int) -> ProbeObservation:
        started = time.perf_counter()
        try:
            result = call(_world_of(world, candidate) if build is None else build(candidate), attempt)
        except Exception as error:  # noqa: BLE001 - the pool could not run it: an error, with its reason
            return ProbeObservation(Outcome.ERROR, wall_time=time.perf_counter() - started,
                                    detail=f"{type(error).__name__}: {error}"[:DETAIL_LIMIT])
        outcome = classify_result(result.error, reference, tolerance if rule is None else rule)
        run = result.run
        detail = ""
        if result.error is not None and outcome is not Outcome.FAIL:
            detail = result.error.describe()[:DETAIL_LIMIT]
        return ProbeObservation(
            outcome=outcome,
            trace=trace_of(run) if run is not None and outcome is Outcome.FAIL else None,
            signature=signature_record(result.error),
            seed=None if run is None else int(run.seed),
            sim_time=0.0 if run is None else float(run.sim_time),
            wall_time=time.perf_counter() - started,
            detail=detail,
        )

    return probe


def _world_of(world: World, candidate: Candidate) -> World:
    """`world.select(candidate)`, or `world` itself when the candidate is all of it: the same object every
    time, which a pool sends to its workers once pickled (`execution.request.SharedWorld`)."""
    return world if tuple(candidate) == world.names else world.select(candidate)


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
    """A precondition: never remove the model under the robot's start (the scenario would change), nor an
    arm's table and target (docs/writing-tests.md, "Arms")."""
    kept: dict[str, str] = {}
    support = start_support(world)
    if support is not None:
        kept[support] = "the model under the robot's start"
    scenario = world.scenario
    if scenario is not None:
        for name, what in ((scenario.table, "the arm's table"), (scenario.target, "the arm's target")):
            if name is not None and name in world.names:
                kept.setdefault(name, what)

    def precondition(candidate: Candidate) -> str | None:
        for name, what in kept.items():
            if name not in candidate:
                return f"removes '{name}', {what}"
        return None

    return precondition
