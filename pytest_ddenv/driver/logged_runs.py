"""The driver's own simulations (the confirmations, the runs for the pictures and the recordings), run and written
in the run log as probe records."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.driver.confirm import ConfirmationRun
from pytest_ddenv.oracle.verdict import classify_result
from pytest_ddenv.reduce import Outcome, ProbeLog, events
from pytest_ddenv.scenario.probe import ProbeResult, signature_record

if TYPE_CHECKING:
    from pytest_ddenv.driver.plan import ReductionPlan
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


def log_run(log: ProbeLog, purpose: str, names: tuple[str, ...], attempt: int, result: ProbeResult | None,
            outcome: str) -> None:
    """A simulation of the driver's own (confirmation, picture) in the run log, as a probe record."""
    run = None if result is None else result.run
    log.write(events.Probe(purpose=purpose, kind=purpose, candidate=names, size=len(names), attempt=attempt,
                           seed=None if run is None else int(run.seed), outcome=outcome,
                           signature=None if result is None else signature_record(result.error),
                           sim_time=0.0 if run is None else float(run.sim_time),
                           wall_time=0.0 if run is None else float(run.wall_time), detail=""))


def logged_run(call: Calls, log: ProbeLog, world: World, attempt: int, purpose: str,
               record: bool) -> tuple[Run | None, bool]:
    """A run of `world` for the pictures (`record`: and the animations, with its full detail), logged: the
    run (None if it cannot be had) and whether it failed the same way."""
    try:
        result = call(world, attempt, record=record)
    except Exception:  # noqa: BLE001 - pictures are a convenience
        log_run(log, purpose, world.names, attempt, None, "error")
        return None, False
    outcome = classify_result(result.error, call.reference, call.rule)
    log_run(log, purpose, world.names, attempt, result, outcome.value)
    return result.run, outcome is Outcome.FAIL


def recorded_original(plan: ReductionPlan, call: Calls, log: ProbeLog,
                      confirmations: tuple[ConfirmationRun, ...]) -> tuple[Run | None, bool]:
    """The original world's failing run with its full detail: the run that confirmed the failure, else one
    more run (attempt 0, logged) when the budget allows; and whether it failed the same way."""
    for _, result, verdict in confirmations:
        if verdict == Outcome.FAIL.value and result is not None and result.run is not None \
                and result.run.detail is not None:
            return result.run, True
    if not call.may_start(plan.spec.max_probes):
        return None, False
    return logged_run(call, log, plan.world, 0, "recording", True)
