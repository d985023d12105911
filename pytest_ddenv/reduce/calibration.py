"""deflake="auto": the original world's failure rate measured before the rounds (or read from a resumed log),
and the deflake rule sized from it. Attempt 0 is the reference failure; these runs are attempts 1, 2, ..."""

from __future__ import annotations

from collections.abc import Callable

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.deflake import CalibratedReruns, ConfirmedRuns
from pytest_ddenv.reduce.extra_runs import ExtraRuns
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.rate_check import RateChecker
from pytest_ddenv.reduce.types import Candidate


def calibrate(policy: CalibratedReruns, original: Candidate, *, log: ProbeLog | None, rates: RateChecker,
              extra_runs: ExtraRuns, write: Callable[[events.Event], None]) -> tuple[tuple[int, int], ConfirmedRuns]:
    """((fails, runs) of the `original` world's calibration runs, the deflake rule they size). First
    `policy.sure_runs` runs, up to `policy.runs` unless all of those failed; a resumed `log` answers with
    its first calibration record (and the runs it logged). A new measurement is logged as "calibration"."""
    known = log.calibration() if log is not None else None
    if known is not None:
        fails, runs = known
        return (fails, runs), policy.rule_for(fails, runs)
    logged = log.measured("calibration", original) if log is not None else {}
    into = rates.record_of(original)
    measure = extra_runs.measure
    fails, runs = measure(original, 1, policy.sure_runs, purpose="calibration", known=logged, strict=True,
                          into=into)
    if fails < runs:
        more = measure(original, 1 + runs, policy.runs - runs, purpose="calibration", known=logged,
                       strict=True, into=into)
        fails, runs = fails + more[0], runs + more[1]
    rule = policy.rule_for(fails, runs)
    write(events.Calibration(fails=fails, runs=runs, rule=rule.label))
    return (fails, runs), rule
