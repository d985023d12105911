"""The first phase of a reduction: does the failure reproduce on the pool? (`confirm`)"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.execution import WorkerError, WorkerStartError
from pytest_ddenv.oracle.verdict import (
    WALL_CLOCK_CAP,
    ErrorInfo,
    FailureReference,
    classify_result,
    wall_clock_cap_message,
)
from pytest_ddenv.reduce import Outcome
from pytest_ddenv.scenario.probe import ProbeResult

if TYPE_CHECKING:
    from collections.abc import Callable

    from pytest_ddenv.oracle.verdict import SameFailureRule
    from pytest_ddenv.world.model import World

AUTO_CONFIRMATIONS = 4
"""Runs that may confirm the failure with deflake="auto"/"adaptive" (1 + the paper's default 3 re-runs)."""


class ConfirmationRun(NamedTuple):
    """One run of the original world that confirmed the failure, or tried to: its result (None: the worker
    failed) and its verdict (`Outcome` value, or "error")."""

    attempt: int
    result: ProbeResult | None
    verdict: str


@dataclass(frozen=True)
class Confirmation:
    """What the confirmation runs found. `status` "confirmed" (the last run failed the same way), else the
    status the reduction ends with ("not-reproducible", "error") and `message`, why."""

    runs: tuple[ConfirmationRun, ...] = ()
    status: str = "confirmed"
    message: str = ""


def confirm(world: World, reference: FailureReference, rule: SameFailureRule, calls: Calls, *,
            deflake: int | str, max_probes: int | None, record: bool, note: Callable[[str], None]) -> Confirmation:
    """Run `world` on fresh attempts (one, then as many as the deflake rule would re-run a candidate) until
    a run fails the same way; `record`: the runs record their full detail (for the animations). A reference
    failure that is the run's wall-clock cap is an error of the run: status "error", no run."""
    if reference.signature is None and reference.exception_type == WALL_CLOCK_CAP:
        return Confirmation((), "error", wall_clock_cap_message(reference.location))
    runs = 1 + deflake if isinstance(deflake, int) else AUTO_CONFIRMATIONS
    if max_probes is not None:
        runs = max(1, min(runs, max_probes))
    done: list[ConfirmationRun] = []
    seen: list[str] = []
    errors: list[str] = []
    for attempt in range(runs):
        note(f"confirming the failure: run {attempt + 1} of up to {runs}")  # it stops at the first that fails
        try:
            result = calls(world, attempt, record=record)
        except WorkerStartError as error:
            return Confirmation(tuple(done), "error", f"the test could not be run in a probe worker: {error}")
        except WorkerError as error:
            errors.append(str(error))
            seen.append("error")
            done.append(ConfirmationRun(attempt, None, "error"))
            continue
        outcome = classify_result(result.error, reference, rule)
        done.append(ConfirmationRun(attempt, result, outcome.value))
        if outcome is Outcome.FAIL:
            return Confirmation(tuple(done))
        if outcome is Outcome.ERROR and result.error is not None:
            errors.append(result.error.describe() + ("\n" + result.error.traceback if result.error.traceback else ""))
        seen.append(outcome.value if result.error is None or outcome is Outcome.ERROR
                    else f"{outcome.value} ({result.error.type_name} at {result.error.location})")
    if errors and len(errors) == runs:
        return Confirmation(tuple(done), "error", "every confirmation run of the test raised an error instead of "
                            f"running; the first one: {errors[0]}")
    raised = _same_exception_every_time(done, runs)
    if raised is not None:
        return Confirmation(tuple(done), "error", (
            f"every confirmation run of the test raised {raised.describe()} instead of failing the same way "
            f"({reference.describe()}): the test behaves differently in a probe than in the pytest process "
            "(an environment variable, a file, state left by other tests?). No reduction was run.\n"
            f"{raised.traceback}"))
    return Confirmation(tuple(done), "not-reproducible", (
        f"not reproducible: 0 of {runs} re-runs failed the same way ({reference.describe()}); they "
        f"gave: {', '.join(seen)}. No reduction was run. The failure may depend on state outside the "
        "world (other fixtures, globals) or on the seed; try a larger --ddenv-deflake."))


def _same_exception_every_time(confirmations: list[ConfirmationRun], runs: int) -> ErrorInfo | None:
    """The exception every confirmation run raised, when they all raised the same one (type and place) and
    it is an error rather than a robot's failure or an assertion: what the test does in a probe, shown as
    it is rather than as "not reproducible"."""
    raised = [result.error for _, result, _ in confirmations if result is not None and result.error is not None]
    if len(raised) != runs or not raised:
        return None
    first = raised[0]
    if first.signature is not None or first.type_name == "AssertionError":
        return None
    if any((error.type_name, error.location) != (first.type_name, first.location) for error in raised):
        return None
    return first
